//! The URDF reader: the elements the dynamics needs (each link's `<inertial>`; each joint's
//! type, frame, links, axis, `<dynamics>`, `<mimic>` and `<limit>`'s effort, a planner's input
//! bound), read in one iterative pass over the XML. Everything else (visuals, collisions,
//! materials, `<gazebo>`, `<transmission>`, position and velocity limits, elements a simulator
//! added) does not affect the dynamics and is not read, so a file the ROS
//! parser takes is taken here. Errors name the element and its line.

use quick_xml::Reader;
use quick_xml::events::{BytesStart, Event};

use super::xml::line_col;
use crate::error::{Error, Result};

#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Pose {
    pub xyz: [f64; 3],
    /// Roll, pitch, yaw (fixed axes).
    pub rpy: [f64; 3],
}

#[derive(Debug, Clone, PartialEq, Default)]
pub struct InertialElement {
    /// The centre-of-mass frame in the link's frame.
    pub origin: Pose,
    pub mass: f64,
    /// ixx, ixy, ixz, iyy, iyz, izz about the centre of mass, in the origin's axes.
    pub inertia: [f64; 6],
}

#[derive(Debug, Clone, PartialEq)]
pub struct Link {
    pub name: String,
    /// The line of its start tag.
    pub line: usize,
    /// The first `<inertial>` (the ROS parser reads the first); None: massless.
    pub inertial: Option<InertialElement>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointType {
    Revolute,
    Continuous,
    Prismatic,
    Fixed,
    Floating,
    Planar,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Mimic {
    /// The joint whose position this one follows.
    pub joint: String,
    pub multiplier: f64,
    pub offset: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    pub name: String,
    pub line: usize,
    pub kind: JointType,
    /// The joint frame in the parent link's frame.
    pub origin: Pose,
    pub parent: String,
    pub child: String,
    /// Not normalised; (1, 0, 0) when absent, as the ROS parser has it.
    pub axis: [f64; 3],
    /// `<dynamics damping friction>`; None when absent.
    pub dynamics: Option<(f64, f64)>,
    /// `<dynamics armature>`, graybox's (docs/robots.md#armature); None when absent.
    pub armature: Option<f64>,
    pub mimic: Option<Mimic>,
    /// `<limit effort>` (N·m or N); None when absent.
    pub effort: Option<f64>,
}

#[derive(Debug, Clone, PartialEq, Default)]
pub struct Robot {
    pub name: String,
    /// The line of `<robot>`.
    pub line: usize,
    pub links: Vec<Link>,
    pub joints: Vec<Joint>,
    /// graybox's own setting in the file, `<graybox coulomb_eps="…"/>` under `<robot>`
    /// (other URDF readers skip an element they do not know).
    pub coulomb_eps: Option<f64>,
}

impl Link {
    /// How errors name it: "link 'x' (line L)".
    pub fn label(&self) -> String {
        format!("link '{}' (line {})", self.name, self.line)
    }
}

impl Joint {
    pub fn label(&self) -> String {
        format!("joint '{}' (line {})", self.name, self.line)
    }
}

fn bad(message: impl Into<String>) -> Error {
    Error::Unprocessable {
        field: "urdf".into(),
        message: message.into(),
    }
}

fn line_of(text: &str, offset: usize) -> usize {
    let before = &text[..text.floor_char_boundary(offset.min(text.len()))];
    before.matches('\n').count() + 1
}

/// One element's attributes, read as the errors about them will name them.
struct Tag<'a> {
    start: BytesStart<'a>,
    /// "<mass> at line L" or "<mass> of link 'x' (line L)".
    at: String,
}

impl Tag<'_> {
    fn text(&self, key: &str) -> Result<Option<String>> {
        match self.start.try_get_attribute(key) {
            Ok(None) => Ok(None),
            Ok(Some(a)) => a
                .unescape_value()
                .map(|v| Some(v.into_owned()))
                .map_err(|e| bad(format!("{}: attribute {key}: {e}", self.at))),
            Err(e) => Err(bad(format!("{}: {e}", self.at))),
        }
    }

    fn required(&self, key: &str) -> Result<String> {
        self.text(key)?
            .ok_or_else(|| bad(format!("{} needs the attribute {key}", self.at)))
    }

    fn number(&self, key: &str, default: Option<f64>) -> Result<f64> {
        let Some(v) = self.text(key)? else {
            return default.ok_or_else(|| bad(format!("{} needs the attribute {key}", self.at)));
        };
        v.trim()
            .parse::<f64>()
            .map_err(|_| bad(format!("{}: {key}=\"{v}\" is not a number", self.at)))
    }

    fn vector(&self, key: &str, default: [f64; 3]) -> Result<[f64; 3]> {
        let Some(v) = self.text(key)? else {
            return Ok(default);
        };
        let parts: Vec<Option<f64>> = v.split_whitespace().map(|p| p.parse().ok()).collect();
        match parts.as_slice() {
            [Some(a), Some(b), Some(c)] => Ok([*a, *b, *c]),
            _ => Err(bad(format!(
                "{}: {key}=\"{v}\" is not three numbers",
                self.at
            ))),
        }
    }

    fn pose(&self) -> Result<Pose> {
        Ok(Pose {
            xyz: self.vector("xyz", [0.0; 3])?,
            rpy: self.vector("rpy", [0.0; 3])?,
        })
    }
}

/// A joint as it is read: its required parts may still be missing.
struct Partial {
    joint: Joint,
    has_parent: bool,
    has_child: bool,
}

/// The st.robot in `text` (bounded beforehand by `xml::precheck`).
pub fn read(text: &str) -> Result<Robot> {
    let mut reader = Reader::from_str(text);
    let mut st = Reading::default();
    loop {
        let offset = reader.buffer_position() as usize;
        let event = reader.read_event().map_err(|e| {
            let at = line_col(text, reader.error_position() as usize);
            bad(format!("not XML: {e} at {at}"))
        })?;
        let (start, opens) = match event {
            Event::Start(s) => (s, true),
            Event::Empty(s) => (s, false),
            Event::End(_) => {
                st.close()?;
                continue;
            }
            Event::Eof => {
                if let Some(open) = st.path.last() {
                    return Err(bad(format!(
                        "not XML: the document ends inside <{}>",
                        String::from_utf8_lossy(open)
                    )));
                }
                break;
            }
            _ => continue,
        };
        let line = line_of(text, offset);
        let name = start.name().as_ref().to_vec();
        let element = String::from_utf8_lossy(&name).into_owned();
        let tag = Tag {
            at: match (&st.link, &st.joint) {
                (Some(l), _) => format!("<{element}> of {}", l.label()),
                (_, Some(j)) => format!("<{element}> of {}", j.joint.label()),
                _ => format!("<{element}> at line {line}"),
            },
            start,
        };
        let parent: Option<&[u8]> = st.path.last().map(|p| p.as_slice());
        match (st.path.len(), parent, name.as_slice()) {
            (0, _, _) if st.robot.is_some() => {
                return Err(bad(format!(
                    "a second root element <{element}> at line {line}: a URDF is one <robot>"
                )));
            }
            (0, _, b"robot") => {
                st.robot = Some(Robot {
                    name: tag.text("name")?.unwrap_or_default(),
                    line,
                    ..Robot::default()
                });
            }
            (0, _, _) => {
                return Err(bad(format!(
                    "the document's root element is <{element}> at line {line}; a URDF's is <robot>"
                )));
            }
            (1, _, b"link") => {
                (st.in_inertial, st.had_inertial) = (false, false);
                st.link = Some(Link {
                    name: named(&tag, "link", line)?,
                    line,
                    inertial: None,
                });
            }
            (1, _, b"joint") => st.joint = Some(start_joint(&tag, line)?),
            (1, _, b"graybox") => {
                if let Some(r) = st.robot.as_mut() {
                    r.coulomb_eps = Some(tag.number("coulomb_eps", None)?);
                }
            }
            (2, Some(b"link"), b"inertial") if !st.had_inertial => {
                (st.in_inertial, st.had_inertial) = (opens, true);
                if let Some(l) = st.link.as_mut() {
                    l.inertial = Some(InertialElement::default());
                }
            }
            (3, Some(b"inertial"), _) if st.in_inertial => {
                let i = st.link.as_mut().and_then(|l| l.inertial.as_mut());
                if let Some(i) = i {
                    inertial_part(i, &tag, &name)?;
                }
            }
            (2, Some(b"joint"), _) => {
                if let Some(j) = st.joint.as_mut() {
                    joint_part(j, &tag, &name)?;
                }
            }
            _ => {}
        }
        if opens {
            st.path.push(name);
        } else if st.path.len() == 1 {
            // `<link name="x"/>` and `<joint …/>` end where they start.
            st.path.push(name);
            st.close()?;
        }
    }
    st.robot
        .ok_or_else(|| bad("the document has no <robot> element"))
}

fn named(tag: &Tag, what: &str, line: usize) -> Result<String> {
    tag.text("name")?
        .ok_or_else(|| bad(format!("a <{what}> at line {line} has no name")))
}

fn start_joint(tag: &Tag, line: usize) -> Result<Partial> {
    let name = named(tag, "joint", line)?;
    let label = format!("joint '{name}' (line {line})");
    let kind = match tag.text("type")?.as_deref() {
        Some("revolute") => JointType::Revolute,
        Some("continuous") => JointType::Continuous,
        Some("prismatic") => JointType::Prismatic,
        Some("fixed") => JointType::Fixed,
        Some("floating") => JointType::Floating,
        Some("planar") => JointType::Planar,
        Some(other) => {
            return Err(bad(format!(
                "{label}: type \"{other}\" is not a URDF joint type (revolute, continuous, \
                 prismatic, fixed, floating, planar)"
            )));
        }
        None => return Err(bad(format!("{label} has no type"))),
    };
    Ok(Partial {
        joint: Joint {
            name,
            line,
            kind,
            origin: Pose::default(),
            parent: String::new(),
            child: String::new(),
            axis: [1.0, 0.0, 0.0],
            dynamics: None,
            armature: None,
            mimic: None,
            effort: None,
        },
        has_parent: false,
        has_child: false,
    })
}

fn inertial_part(i: &mut InertialElement, tag: &Tag, name: &[u8]) -> Result<()> {
    match name {
        b"origin" => i.origin = tag.pose()?,
        b"mass" => i.mass = tag.number("value", None)?,
        b"inertia" => {
            let keys = ["ixx", "ixy", "ixz", "iyy", "iyz", "izz"];
            for (v, key) in i.inertia.iter_mut().zip(keys) {
                *v = tag.number(key, None)?;
            }
        }
        _ => {}
    }
    Ok(())
}

fn joint_part(p: &mut Partial, tag: &Tag, name: &[u8]) -> Result<()> {
    let j = &mut p.joint;
    match name {
        b"origin" => j.origin = tag.pose()?,
        b"parent" => (j.parent, p.has_parent) = (tag.required("link")?, true),
        b"child" => (j.child, p.has_child) = (tag.required("link")?, true),
        b"axis" => j.axis = tag.vector("xyz", [1.0, 0.0, 0.0])?,
        b"dynamics" => {
            j.dynamics = Some((
                tag.number("damping", Some(0.0))?,
                tag.number("friction", Some(0.0))?,
            ));
            if tag.text("armature")?.is_some() {
                j.armature = Some(tag.number("armature", None)?);
            }
        }
        // Only the effort: a planner's input bounds (`UrdfTemplate::effort_limits`).
        b"limit" if tag.text("effort")?.is_some() => j.effort = Some(tag.number("effort", None)?),
        b"mimic" => {
            j.mimic = Some(Mimic {
                joint: tag.required("joint")?,
                multiplier: tag.number("multiplier", Some(1.0))?,
                offset: tag.number("offset", Some(0.0))?,
            });
        }
        _ => {}
    }
    Ok(())
}

/// What `read` holds while it reads.
#[derive(Default)]
struct Reading {
    robot: Option<Robot>,
    /// The names of the open elements, the root first.
    path: Vec<Vec<u8>>,
    link: Option<Link>,
    joint: Option<Partial>,
    /// Whether the open link's first <inertial> is being read, and whether it was.
    in_inertial: bool,
    had_inertial: bool,
}

impl Reading {
    /// An element ends: a finished link or joint joins the robot.
    fn close(&mut self) -> Result<()> {
        let depth = self.path.len();
        let Some(name) = self.path.pop() else {
            return Ok(());
        };
        match (depth, name.as_slice()) {
            (3, b"inertial") => self.in_inertial = false,
            (2, b"link") => {
                if let (Some(r), Some(l)) = (self.robot.as_mut(), self.link.take()) {
                    r.links.push(l);
                }
            }
            (2, b"joint") => {
                if let (Some(r), Some(p)) = (self.robot.as_mut(), self.joint.take()) {
                    for (has, what) in [(p.has_parent, "parent"), (p.has_child, "child")] {
                        if !has {
                            return Err(bad(format!(
                                "{} has no <{what} link=\"…\"/>",
                                p.joint.label()
                            )));
                        }
                    }
                    r.joints.push(p.joint);
                }
            }
            _ => {}
        }
        Ok(())
    }
}
