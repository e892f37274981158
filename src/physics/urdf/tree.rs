//! A URDF robot as the kinematic tree the dynamics needs: one body per movable joint (the
//! joint's child link with every link fixed to it folded in), in depth-first order from the
//! root with children in document order; those bodies' joints are the coordinates.

use std::collections::HashMap;

use super::inertia::Inertial;
use crate::error::{Error, Result};
use crate::names::{name_problem, quoted_name};
use crate::physics::params::physical_problem;

pub type Rot = [[f64; 3]; 3];

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
}

#[derive(Debug, Clone, PartialEq)]
pub struct Tree {
    pub robot: String,
    pub bodies: Vec<Body>,
}

fn bad(message: impl Into<String>) -> Error {
    Error::Unprocessable {
        field: "urdf".into(),
        message: message.into(),
    }
}

/// R = Rz(yaw) Ry(pitch) Rx(roll), URDF's fixed-axis roll-pitch-yaw.
pub fn rpy(r: [f64; 3]) -> Rot {
    let (sr, cr) = r[0].sin_cos();
    let (sp, cp) = r[1].sin_cos();
    let (sy, cy) = r[2].sin_cos();
    [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
}

fn mul(a: &Rot, b: &Rot) -> Rot {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

fn apply(a: &Rot, v: &[f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| (0..3).map(|k| a[i][k] * v[k]).sum())
}

/// A rigid transform (rotation, translation): x ↦ R x + p.
#[derive(Clone, Copy)]
struct Frame {
    rot: Rot,
    pos: [f64; 3],
}

impl Frame {
    const IDENTITY: Frame = Frame {
        rot: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        pos: [0.0; 3],
    };

    fn of(pose: &urdf_rs::Pose) -> Frame {
        Frame {
            rot: rpy(pose.rpy.0),
            pos: pose.xyz.0,
        }
    }

    fn then(&self, o: &Frame) -> Frame {
        let p = apply(&self.rot, &o.pos);
        Frame {
            rot: mul(&self.rot, &o.rot),
            pos: std::array::from_fn(|i| self.pos[i] + p[i]),
        }
    }
}

/// Every physical value of a document within the one bound (`templates::physical_problem`;
/// no lower one: a URDF's tiny inertias are taken, `link_inertial`).
fn within(at: &str, what: &str, v: f64) -> Result<()> {
    physical_problem(v, false).map_or(Ok(()), |m| Err(bad(format!("{at} {what} {m}"))))
}

fn pose_within(at: &str, pose: &urdf_rs::Pose) -> Result<()> {
    for (k, v) in pose.xyz.0.iter().enumerate() {
        within(at, &format!("<origin> xyz[{k}]"), *v)?;
    }
    for (k, v) in pose.rpy.0.iter().enumerate() {
        within(at, &format!("<origin> rpy[{k}]"), *v)?;
    }
    Ok(())
}

/// Link, joint and robot names follow the rule of every name (`names::name_problem`).
fn named(what: &str, name: &str) -> Result<()> {
    name_problem(name).map_or(Ok(()), |m| {
        Err(bad(format!("{what} '{}': its name {m}", quoted_name(name))))
    })
}

/// A link's own inertial parameters in its frame, as the file gives them; an error naming it
/// when they are not a physical body. A nearly singular one (no `<inertial>`, a point mass, a
/// thin rod) is taken as it is: only the trainable form needs the floors
/// (`Inertial::regularised`, `UrdfTemplate::raw`).
fn link_inertial(link: &urdf_rs::Link) -> Result<Inertial> {
    let i = &link.inertial;
    let m = i.mass.value;
    let t = &i.inertia;
    let values = [
        ("mass", m),
        ("ixx", t.ixx),
        ("ixy", t.ixy),
        ("ixz", t.ixz),
        ("iyy", t.iyy),
        ("iyz", t.iyz),
        ("izz", t.izz),
    ];
    let at = format!("link '{}': <inertial>", link.name);
    for (what, v) in values {
        within(&at, what, v)?;
    }
    pose_within(&at, &i.origin)?;
    if m < 0.0 {
        return Err(bad(format!("{at} needs a mass ≥ 0")));
    }
    let at_com = [
        [t.ixx, t.ixy, t.ixz],
        [t.ixy, t.iyy, t.iyz],
        [t.ixz, t.iyz, t.izz],
    ];
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
    let body = Inertial::from_com(m, frame.pos, rotated);
    body.regularised().theta().map_err(|e| {
        let why = match e {
            Error::Invalid { message, .. } => message,
            other => other.to_string(),
        };
        bad(format!("link '{}': <inertial> {why}", link.name))
    })?;
    Ok(body)
}

impl Tree {
    /// The robot's tree from URDF text with at most `max_dof` movable joints; errors (422,
    /// field "urdf") name the element.
    pub fn parse(text: &str, max_dof: usize) -> Result<Tree> {
        super::xml::precheck(text, max_dof)?;
        let robot = urdf_rs::read_from_string(text).map_err(|e| bad(format!("not a URDF: {e}")))?;
        let mut links: HashMap<&str, &urdf_rs::Link> = HashMap::new();
        named("robot", &robot.name)?;
        for l in &robot.links {
            named("link", &l.name)?;
            if links.insert(l.name.as_str(), l).is_some() {
                return Err(bad(format!("link '{}' is defined twice", l.name)));
            }
        }
        let mut parent_of: HashMap<&str, &str> = HashMap::new();
        let mut joint_names = std::collections::HashSet::new();
        for j in &robot.joints {
            named("joint", &j.name)?;
            pose_within(&format!("joint '{}':", j.name), &j.origin)?;
            if !joint_names.insert(j.name.as_str()) {
                return Err(bad(format!("joint '{}' is defined twice", j.name)));
            }
            use urdf_rs::JointType::*;
            match j.joint_type {
                Revolute | Continuous | Prismatic | Fixed => {}
                ref other => {
                    return Err(bad(format!(
                        "joint '{}': type {other:?} is not supported (revolute, continuous, \
                         prismatic and fixed are)",
                        j.name
                    )));
                }
            }
            if j.mimic.is_some() {
                return Err(bad(format!(
                    "joint '{}': mimic joints are not supported",
                    j.name
                )));
            }
            for (role, link) in [("parent", &j.parent.link), ("child", &j.child.link)] {
                if !links.contains_key(link.as_str()) {
                    return Err(bad(format!(
                        "joint '{}': its {role} link '{link}' does not exist",
                        j.name
                    )));
                }
            }
            if let Some(other) = parent_of.insert(j.child.link.as_str(), j.name.as_str()) {
                return Err(bad(format!(
                    "link '{}' is the child of two joints, '{other}' and '{}' (a URDF is a tree)",
                    j.child.link, j.name
                )));
            }
        }
        let roots: Vec<&str> = robot
            .links
            .iter()
            .map(|l| l.name.as_str())
            .filter(|l| !parent_of.contains_key(l))
            .collect();
        let root = match roots.as_slice() {
            [one] => *one,
            [] => return Err(bad("no root link: the joints form a loop")),
            many => {
                return Err(bad(format!(
                    "more than one root link ({}): a robot is one tree",
                    many.join(", ")
                )));
            }
        };
        let mut tree = Tree {
            robot: robot.name.clone(),
            bodies: vec![],
        };
        let visited = tree.walk(&robot, &links, root)?;
        if visited != robot.links.len() {
            return Err(bad(
                "some links are not reachable from the root: the joints form a loop",
            ));
        }
        if tree.bodies.is_empty() {
            return Err(bad(
                "the robot has no revolute, continuous or prismatic joint",
            ));
        }
        Ok(tree)
    }

    /// Depth-first from the root, children in document order, on a stack of its own (a
    /// chain of thousands of links is a legal robot); the links visited.
    fn walk(
        &mut self,
        robot: &urdf_rs::Robot,
        links: &HashMap<&str, &urdf_rs::Link>,
        root: &str,
    ) -> Result<usize> {
        let mut children: HashMap<&str, Vec<&urdf_rs::Joint>> = HashMap::new();
        for j in &robot.joints {
            children.entry(j.parent.link.as_str()).or_default().push(j);
        }
        // A link to visit, with the body that moves it and the frame from that body's frame
        // to the link's; or a movable joint whose body is made when its turn comes, so that
        // bodies are numbered in depth-first order.
        enum Next<'r> {
            Link(&'r str, Option<usize>, Frame),
            Joint(&'r urdf_rs::Joint, Option<usize>, Frame),
        }
        let mut stack = vec![Next::Link(root, None, Frame::IDENTITY)];
        let mut visited = 0usize;
        while let Some(next) = stack.pop() {
            let (link, body, frame) = match next {
                Next::Link(link, body, frame) => (link, body, frame),
                Next::Joint(j, parent, at) => {
                    self.bodies.push(movable_body(j, parent, at)?);
                    let b = self.bodies.len() - 1;
                    (j.child.link.as_str(), Some(b), Frame::IDENTITY)
                }
            };
            visited += 1;
            self.fold(links[link], body, &frame)?;
            for j in children.get(link).into_iter().flatten().rev() {
                let at = frame.then(&Frame::of(&j.origin));
                stack.push(match j.joint_type {
                    urdf_rs::JointType::Fixed => Next::Link(&j.child.link, body, at),
                    _ => Next::Joint(j, body, at),
                });
            }
        }
        Ok(visited)
    }

    /// Adds `link`'s inertia to the body that moves it (seen from that body's frame). The
    /// root and the links welded to it never move, so their inertia never enters the
    /// dynamics and is not read: quadruped files carry dummy, unphysical values there.
    fn fold(&mut self, link: &urdf_rs::Link, body: Option<usize>, frame: &Frame) -> Result<()> {
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

/// The body a movable joint moves, with no inertia yet; `at` is the joint frame in the
/// parent body's frame.
fn movable_body(j: &urdf_rs::Joint, parent: Option<usize>, at: Frame) -> Result<Body> {
    let kind = match j.joint_type {
        urdf_rs::JointType::Prismatic => JointKind::Prismatic,
        urdf_rs::JointType::Continuous => JointKind::Continuous,
        _ => JointKind::Revolute,
    };
    let a = j.axis.xyz.0;
    let norm = a.iter().map(|v| v * v).sum::<f64>().sqrt();
    if !(norm.is_finite() && norm > 1e-9) {
        return Err(bad(format!(
            "joint '{}': its axis must not be zero",
            j.name
        )));
    }
    let (damping, friction) = j
        .dynamics
        .as_ref()
        .map_or((0.0, 0.0), |d| (d.damping, d.friction));
    // Bounded here; their sign is the template's rule (`UrdfTemplate::from_doc`).
    let joint = format!("joint '{}':", j.name);
    within(&joint, "<dynamics> damping", damping)?;
    within(&joint, "<dynamics> friction", friction)?;
    Ok(Body {
        joint: j.name.clone(),
        kind,
        link: j.child.link.clone(),
        parent,
        rot: at.rot,
        pos: at.pos,
        axis: a.map(|v| v / norm),
        inertial: Inertial::ZERO,
        own: Inertial::ZERO,
        fixed: vec![],
        damping,
        friction,
    })
}
