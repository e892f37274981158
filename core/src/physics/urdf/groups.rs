//! Where a URDF template's optional groups sit among its physical values: after the bodies'
//! ten and the joints' two, the armatures (one per coordinate), the effort gains and offsets
//! (one per input) and the effort delay (one), each only when the document asks for it.

use super::parameters::{PER_BODY, PER_JOINT};
use super::template::UrdfTemplate;

impl UrdfTemplate {
    /// The start and length of group `which` (in the order above).
    fn group(&self, which: usize) -> (usize, usize) {
        let d = &self.doc;
        let sizes = [
            if d.armature { self.n() } else { 0 },
            if d.effort_gain { self.m() } else { 0 },
            if d.effort_offset { self.m() } else { 0 },
            usize::from(d.effort_delay.is_some()),
        ];
        let start = (PER_BODY + PER_JOINT) * self.nb() + sizes[..which].iter().sum::<usize>();
        (start, sizes[which])
    }

    fn slice<'p, S>(&self, p: &'p [S], which: usize) -> &'p [S] {
        let (start, len) = self.group(which);
        &p[start.min(p.len())..][..len]
    }

    /// The armatures of physical values, one per coordinate (none when the robot has none).
    pub fn armature<'p, S>(&self, p: &'p [S]) -> &'p [S] {
        self.slice(p, 0)
    }

    /// The inputs' effort gains (none when the robot has none).
    pub fn effort_gain<'p, S>(&self, p: &'p [S]) -> &'p [S] {
        self.slice(p, 1)
    }

    /// The inputs' effort offsets (none when the robot has none).
    pub fn effort_offset<'p, S>(&self, p: &'p [S]) -> &'p [S] {
        self.slice(p, 2)
    }

    /// The efforts' delay behind the motion, seconds (none when the robot has none).
    pub fn effort_delay<'p, S>(&self, p: &'p [S]) -> Option<&'p S> {
        self.slice(p, 3).first()
    }
}
