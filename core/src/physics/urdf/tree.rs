//! A URDF robot as the kinematic tree the dynamics needs: one body per movable joint (the
//! joint's child link with every link fixed to it folded in), in depth-first order from the
//! root with children in document order. The bodies' joints are the coordinates, but for mimic
//! joints, which follow another joint's value.

use std::collections::{HashMap, HashSet};

use super::read::{self, JointType, Mimic, Pose};
use crate::error::{Error, Result};
use crate::names::{name_problem, quoted_name};
pub use crate::physics::multibody::Drive;
use crate::physics::multibody::Inertial;
use crate::physics::params::physical_problem;

use super::frame::Frame;
pub use super::frame::{Rot, rpy};

/// How a joint moves its body.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    Revolute,
    /// A revolute joint without limits: periodic by default.
    Continuous,
    Prismatic,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    /// The movable joint (the coordinate's name).
    pub joint: String,
    pub kind: JointKind,
    /// The link it moves (the parameters' name; fixed children are folded into it).
    pub link: String,
    /// The body this one hangs from (None: the fixed base).
    pub parent: Option<usize>,
    /// The joint frame in the parent body's frame (fixed joints on the way folded in).
    pub rot: Rot,
    pub pos: [f64; 3],
    /// The joint axis (unit) in the joint frame, which is this body's frame.
    pub axis: [f64; 3],
    /// Everything the joint moves rigidly, in this body's frame.
    pub inertial: Inertial,
    /// The link's own part of `inertial` (without the links fixed to it), as the export
    /// writes it back.
    pub own: Inertial,
    /// The links fixed to it, each with its frame in this body's frame.
    pub fixed: Vec<(String, Rot, [f64; 3])>,
    /// URDF `<dynamics damping friction>` (0 when absent).
    pub damping: f64,
    pub friction: f64,
    /// `<dynamics armature>` (graybox's; a mimic joint has none of its own).
    pub armature: Option<f64>,
    /// The joint it mimics, as the URDF says.
    pub mimic: Option<Mimic>,
    pub drive: Drive,
    /// URDF `<limit effort>` when positive: the most the joint's actuator exerts.
    pub effort: Option<f64>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Tree {
    pub robot: String,
    pub bodies: Vec<Body>,
    /// The body of each coordinate: every body whose joint is not a mimic joint.
    pub coordinates: Vec<usize>,
    /// The file's `<graybox coulomb_eps>`, when it has one (`settings.rs`).
    pub coulomb_eps: Option<f64>,
}

pub(super) fn bad(message: impl Into<String>) -> Error {
    Error::Unprocessable {
        field: "urdf".into(),
        message: message.into(),
    }
}

/// Every physical value of a document within the one bound (`templates::physical_problem`;
/// no lower one: a URDF's tiny inertias are taken, `link_inertial`).
fn within(at: &str, what: &str, v: f64) -> Result<()> {
    physical_problem(v, false).map_or(Ok(()), |m| Err(bad(format!("{at} {what} {m}"))))
}

fn pose_within(at: &str, pose: &Pose) -> Result<()> {
    for (k, v) in pose.xyz.iter().enumerate() {
        within(at, &format!("<origin> xyz[{k}]"), *v)?;
    }
    for (k, v) in pose.rpy.iter().enumerate() {
        within(at, &format!("<origin> rpy[{k}]"), *v)?;
    }
    Ok(())
}

/// Link, joint and robot names follow the rule of every name (`names::name_problem`).
fn named(what: &str, name: &str, line: usize) -> Result<()> {
    name_problem(name).map_or(Ok(()), |m| {
        Err(bad(format!(
            "{what} '{}' (line {line}): its name {m}",
            quoted_name(name)
        )))
    })
}

/// A link's own inertial parameters in its frame, as the file has them (within the bounds of
/// every value; whether they are a physical body is asked of the whole body it belongs to).
fn link_inertial(link: &read::Link) -> Result<Inertial> {
    let i = link.inertial.clone().unwrap_or_default();
    let m = i.mass;
    let [ixx, ixy, ixz, iyy, iyz, izz] = i.inertia;
    let values = [
        ("mass", m),
        ("ixx", ixx),
        ("ixy", ixy),
        ("ixz", ixz),
        ("iyy", iyy),
        ("iyz", iyz),
        ("izz", izz),
    ];
    let at = format!("{}: <inertial>", link.label());
    for (what, v) in values {
        within(&at, what, v)?;
    }
    pose_within(&at, &i.origin)?;
    if m < 0.0 {
        return Err(bad(format!("{at} needs a mass ≥ 0")));
    }
    let at_com = [[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]];
    let frame = Frame::of(&i.origin);
    let r = frame.rot;
    // The inertia about the centre of mass, turned from the <inertial> frame to the link's.
    let rotated: Rot = std::array::from_fn(|a| {
        std::array::from_fn(|b| {
            (0..3)
                .flat_map(|k| (0..3).map(move |l| (k, l)))
                .map(|(k, l)| r[a][k] * at_com[k][l] * r[b][l])
                .sum()
        })
    });
    Ok(Inertial::from_com(m, frame.pos, rotated))
}

/// Whether a body can be trained: physical once regularised (a nearly singular one, a point
/// mass or a link without mass: `Inertial::regularised`), or an error naming its link and the
/// links fixed to it. Only the whole body is asked: a link welded to it may carry a dummy
/// value (a massless foot's) that the whole absorbs. The body keeps the file's values.
fn physical_body(b: &Body, links: &HashMap<&str, &read::Link>) -> Result<()> {
    b.inertial.regularised().theta().map_err(|e| {
        let why = match e {
            Error::Invalid { message, .. } => message,
            other => other.to_string(),
        };
        let fixed: Vec<String> = b
            .fixed
            .iter()
            .map(|(l, ..)| links[l.as_str()].label())
            .collect();
        let with = match fixed.as_slice() {
            [] => String::new(),
            some => format!(" with the links fixed to it ({})", some.join(", ")),
        };
        bad(format!(
            "{}{with}: <inertial> {why}",
            links[b.link.as_str()].label()
        ))
    })?;
    Ok(())
}

impl Tree {
    /// The robot's tree from URDF text with at most `max_dof` movable joints; errors (422,
    /// field "urdf") name the element and its line.
    pub fn parse(text: &str, max_dof: usize) -> Result<Tree> {
        super::xml::precheck(text, max_dof)?;
        let robot = read::read(text)?;
        if !robot.name.is_empty() {
            named("robot", &robot.name, robot.line)?;
        }
        if robot.links.is_empty() {
            return Err(bad("the robot has no <link>"));
        }
        let mut links: HashMap<&str, &read::Link> = HashMap::new();
        for l in &robot.links {
            named("link", &l.name, l.line)?;
            if let Some(first) = links.insert(l.name.as_str(), l) {
                return Err(bad(format!(
                    "{} is defined twice (first at line {})",
                    l.label(),
                    first.line
                )));
            }
        }
        let parent_of = check_joints(&robot, &links)?;
        let roots: Vec<&str> = robot
            .links
            .iter()
            .map(|l| l.name.as_str())
            .filter(|l| !parent_of.contains_key(l))
            .collect();
        let root = match roots.as_slice() {
            [one] => *one,
            [] => {
                let j = parent_of[robot.links[0].name.as_str()];
                return Err(bad(format!(
                    "no root link: every link is a joint's child, so the joints form a loop \
                     (link '{}' is the child of {}, …)",
                    j.child,
                    j.label()
                )));
            }
            many => {
                let named: Vec<String> = many.iter().map(|l| links[l].label()).collect();
                return Err(bad(format!(
                    "more than one root link ({}): a robot is one tree",
                    named.join(", ")
                )));
            }
        };
        let mut tree = Tree {
            robot: robot.name.clone(),
            bodies: vec![],
            coordinates: vec![],
            coulomb_eps: robot.coulomb_eps,
        };
        let visited = tree.walk(&robot, &links, root)?;
        if visited.len() != robot.links.len() {
            let apart: Vec<String> = (robot.links.iter())
                .filter(|l| !visited.contains(l.name.as_str()))
                .take(3)
                .map(read::Link::label)
                .collect();
            return Err(bad(format!(
                "{} … are not reachable from the root link '{root}': their joints form a loop",
                apart.join(", ")
            )));
        }
        if tree.bodies.is_empty() {
            return Err(bad(
                "the robot has no revolute, continuous or prismatic joint",
            ));
        }
        for b in &tree.bodies {
            physical_body(b, &links)?;
        }
        tree.drives(&robot)?;
        Ok(tree)
    }

    /// Depth-first from the root, children in document order, on a stack of its own (a
    /// chain of thousands of links is a legal robot); the links visited.
    fn walk<'r>(
        &mut self,
        robot: &'r read::Robot,
        links: &HashMap<&str, &read::Link>,
        root: &'r str,
    ) -> Result<HashSet<&'r str>> {
        let mut children: HashMap<&str, Vec<&read::Joint>> = HashMap::new();
        for j in &robot.joints {
            children.entry(j.parent.as_str()).or_default().push(j);
        }
        // A link to visit, with the body that moves it and the frame from that body's frame
        // to the link's; or a movable joint whose body is made when its turn comes, so that
        // bodies are numbered in depth-first order.
        enum Next<'r> {
            Link(&'r str, Option<usize>, Frame),
            Joint(&'r read::Joint, Option<usize>, Frame),
        }
        let mut stack = vec![Next::Link(root, None, Frame::IDENTITY)];
        let mut visited = HashSet::new();
        while let Some(next) = stack.pop() {
            let (link, body, frame) = match next {
                Next::Link(link, body, frame) => (link, body, frame),
                Next::Joint(j, parent, at) => {
                    self.bodies.push(movable_body(j, parent, at)?);
                    let b = self.bodies.len() - 1;
                    (j.child.as_str(), Some(b), Frame::IDENTITY)
                }
            };
            visited.insert(link);
            self.fold(links[link], body, &frame)?;
            for j in children.get(link).into_iter().flatten().rev() {
                let at = frame.then(&Frame::of(&j.origin));
                stack.push(match j.kind {
                    JointType::Fixed => Next::Link(&j.child, body, at),
                    _ => Next::Joint(j, body, at),
                });
            }
        }
        Ok(visited)
    }

    /// Adds `link`'s inertia to the body that moves it (seen from that body's frame). The
    /// root and the links welded to it never move, so their inertia never enters the
    /// dynamics and is not read: quadruped files carry dummy, unphysical values there.
    fn fold(&mut self, link: &read::Link, body: Option<usize>, frame: &Frame) -> Result<()> {
        let Some(b) = body else {
            return Ok(());
        };
        let own = link_inertial(link)?;
        let moved = own.transformed(&frame.rot, &frame.pos);
        let target = &mut self.bodies[b];
        if target.link == link.name {
            target.own = own.clone();
        } else {
            target.fixed.push((link.name.clone(), frame.rot, frame.pos));
        }
        target.inertial = target.inertial.plus(&moved);
        Ok(())
    }
}

/// Joint names and types, their links, one parent per link; the joint each child link hangs
/// from.
fn check_joints<'r>(
    robot: &'r read::Robot,
    links: &HashMap<&str, &read::Link>,
) -> Result<HashMap<&'r str, &'r read::Joint>> {
    let mut parent_of: HashMap<&str, &read::Joint> = HashMap::new();
    let mut joints: HashMap<&str, usize> = HashMap::new();
    for j in &robot.joints {
        named("joint", &j.name, j.line)?;
        let label = j.label();
        pose_within(&format!("{label}:"), &j.origin)?;
        if let Some(first) = joints.insert(j.name.as_str(), j.line) {
            return Err(bad(format!(
                "{label} is defined twice (first at line {first})"
            )));
        }
        if matches!(j.kind, JointType::Floating | JointType::Planar) {
            return Err(bad(format!(
                "{label}: type {:?} is not supported (revolute, continuous, prismatic and \
                 fixed are)",
                j.kind
            )));
        }
        for (role, link) in [("parent", &j.parent), ("child", &j.child)] {
            if !links.contains_key(link.as_str()) {
                return Err(bad(format!(
                    "{label}: its {role} link '{link}' does not exist"
                )));
            }
        }
        if let Some(other) = parent_of.insert(j.child.as_str(), j) {
            return Err(bad(format!(
                "link '{}' is the child of two joints, {} and {label} (a URDF is a tree)",
                j.child,
                other.label()
            )));
        }
    }
    Ok(parent_of)
}

/// The body a movable joint moves, with no inertia yet; `at` is the joint frame in the
/// parent body's frame.
fn movable_body(j: &read::Joint, parent: Option<usize>, at: Frame) -> Result<Body> {
    let kind = match j.kind {
        JointType::Prismatic => JointKind::Prismatic,
        JointType::Continuous => JointKind::Continuous,
        _ => JointKind::Revolute,
    };
    let label = j.label();
    let a = j.axis;
    let norm = a.iter().map(|v| v * v).sum::<f64>().sqrt();
    if !(norm.is_finite() && norm > 1e-9) {
        return Err(bad(format!("{label}: its axis must not be zero")));
    }
    let (damping, friction) = j.dynamics.unwrap_or((0.0, 0.0));
    // Bounded here; their sign is the template's rule (`UrdfTemplate::from_doc`).
    let joint = format!("{label}:");
    within(&joint, "<dynamics> damping", damping)?;
    within(&joint, "<dynamics> friction", friction)?;
    if let Some(a) = j.armature {
        within(&joint, "<dynamics> armature", a)?;
        if j.mimic.is_some() {
            return Err(bad(format!(
                "{joint} a mimic joint has no armature of its own: give the rotor's on the \
                 joint it follows"
            )));
        }
    }
    if let Some(e) = j.effort.filter(|e| !(e.is_finite() && *e >= 0.0)) {
        return Err(bad(format!(
            "{joint} <limit> effort must be a finite value ≥ 0, got {e}"
        )));
    }
    if let Some(m) = &j.mimic {
        within(&joint, "<mimic> multiplier", m.multiplier)?;
        within(&joint, "<mimic> offset", m.offset)?;
    }
    Ok(Body {
        joint: j.name.clone(),
        kind,
        link: j.child.clone(),
        parent,
        rot: at.rot,
        pos: at.pos,
        axis: a.map(|v| v / norm),
        inertial: Inertial::ZERO,
        own: Inertial::ZERO,
        fixed: vec![],
        damping,
        friction,
        armature: j.armature,
        mimic: j.mimic.clone(),
        drive: Drive {
            coordinate: 0,
            multiplier: 1.0,
            offset: 0.0,
        },
        effort: j.effort.filter(|&e| e > 0.0),
    })
}
