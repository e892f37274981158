//! The identified robot as URDF: the template's own document with each moving link's
//! `<inertial>` and each movable joint's `<dynamics>` rewritten, and every other byte
//! (visuals, collisions, comments, formatting) as it was. A text edit, not a re-serialisation:
//! no XML writer keeps comments and layout. Elements are found by an XML reader and every
//! export is read back by the URDF reader before anyone gets it.

use std::collections::HashMap;

use quick_xml::Reader;
use quick_xml::events::Event;

use super::read;
use super::template::{UrdfDoc, UrdfTemplate};
use super::xml::line_col;
use crate::error::{Error, Result};
use crate::physics::multibody::Inertial;

/// An element of the document: its name, the `name` attribute, and byte spans.
#[derive(Debug, Clone)]
struct Element {
    tag: String,
    /// Unescaped, as the URDF reader gives the template its names.
    name: Option<String>,
    /// The start tag `<tag …>` (or the whole `<tag …/>`).
    open: (usize, usize),
    /// The end tag `</tag>`; None for an empty element.
    close: Option<(usize, usize)>,
    depth: usize,
}

/// Every element of `text` in document order, located by an XML reader (the one `xml.rs`
/// bounds the document with), so that quoting, entities and markup that only looks like a
/// tag are read as the URDF reader reads them.
fn elements(text: &str) -> Result<Vec<Element>> {
    let corrupt = |why: String| Error::corrupt("urdf", why);
    let mut reader = Reader::from_str(text);
    let mut out: Vec<Element> = vec![];
    let mut open: Vec<usize> = vec![];
    loop {
        let start = reader.buffer_position() as usize;
        let event = reader.read_event().map_err(|e| {
            let at = line_col(text, reader.error_position() as usize);
            corrupt(format!("not XML: {e} at {at}"))
        })?;
        let end = reader.buffer_position() as usize;
        let (s, opens) = match event {
            Event::Start(s) => (s, true),
            Event::Empty(s) => (s, false),
            Event::End(_) => {
                let e = open
                    .pop()
                    .ok_or_else(|| corrupt("unbalanced end tag".into()))?;
                out[e].close = Some((start, end));
                continue;
            }
            Event::Eof => break,
            _ => continue,
        };
        // The spans are what the edits replace: a position that is not a tag's would cut
        // the document anywhere.
        if !(text
            .get(start..end)
            .is_some_and(|t| t.starts_with('<') && t.ends_with('>')))
        {
            return Err(Error::Internal(format!(
                "URDF export: the XML reader's position {start}..{end} is not a tag"
            )));
        }
        let name = match s.try_get_attribute("name") {
            Ok(Some(a)) => Some(
                a.decode_and_unescape_value(reader.decoder())
                    .map_err(|e| corrupt(format!("a name at {}: {e}", line_col(text, start))))?
                    .into_owned(),
            ),
            Ok(None) => None,
            Err(e) => return Err(corrupt(format!("{e} at {}", line_col(text, start)))),
        };
        out.push(Element {
            tag: String::from_utf8_lossy(s.name().as_ref()).into_owned(),
            name,
            open: (start, end),
            close: None,
            depth: open.len(),
        });
        if opens {
            open.push(out.len() - 1);
        }
    }
    Ok(out)
}

/// The indentation of the line `at` is on.
fn indent_at(text: &str, at: usize) -> &str {
    let line = text[..at].rfind('\n').map_or(0, |k| k + 1);
    let ws = text[line..at].len() - text[line..at].trim_start().len();
    &text[line..line + ws]
}

/// What an `<inertial>` says: mass, centre of mass (its origin, no rotation), and the moments
/// ixx, ixy, ixz, iyy, iyz, izz about the centre of mass in the link's axes.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Written {
    mass: f64,
    com: [f64; 3],
    moments: [f64; 6],
}

/// What a link merged into the body it is fixed to is written with when the identified body
/// cannot be split between them: a token body at its frame's origin, not mass 0, which some
/// simulators refuse (a real robot file's dummy values are of this size). Its owner's values
/// are the identified whole less it, so the model reads back the same.
pub const MERGED_LINK_MASS: f64 = 1e-6;
pub const MERGED_LINK_INERTIA: f64 = 1e-9;

impl Written {
    const MERGED: Written = Written {
        mass: MERGED_LINK_MASS,
        com: [0.0; 3],
        moments: [
            MERGED_LINK_INERTIA,
            0.0,
            0.0,
            MERGED_LINK_INERTIA,
            0.0,
            MERGED_LINK_INERTIA,
        ],
    };

    fn inertial(&self) -> Inertial {
        let [xx, xy, xz, yy, yz, zz] = self.moments;
        Inertial::from_com(
            self.mass,
            self.com,
            [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]],
        )
    }

    fn of(body: &Inertial) -> Written {
        let i = body.inertia_at_com();
        Written {
            mass: body.mass,
            com: body.com(),
            moments: [i[0][0], i[0][1], i[0][2], i[1][1], i[1][2], i[2][2]],
        }
    }

    /// Origin xyz and rpy, mass, moments: what the URDF reader gives for it.
    fn values(&self) -> [f64; 13] {
        let mut v = [0.0; 13];
        v[..3].copy_from_slice(&self.com);
        v[6] = self.mass;
        v[7..].copy_from_slice(&self.moments);
        v
    }

    /// The element, every number in Rust's shortest round-trip form (so the reader gives
    /// back these exact values).
    fn xml(&self, indent: &str, step: &str) -> String {
        let (c, i) = (self.com, self.moments);
        format!(
            "<inertial>\n{indent}{step}<origin xyz=\"{} {} {}\" rpy=\"0 0 0\"/>\n\
             {indent}{step}<mass value=\"{}\"/>\n\
             {indent}{step}<inertia ixx=\"{}\" ixy=\"{}\" ixz=\"{}\" iyy=\"{}\" iyz=\"{}\" izz=\"{}\"/>\n\
             {indent}</inertial>",
            c[0], c[1], c[2], self.mass, i[0], i[1], i[2], i[3], i[4], i[5]
        )
    }
}

/// `text` fit for an XML comment, which may not hold `--` (a link named `a--b` would end the
/// comment early or make the document not XML). The note around it never ends in `-`.
fn in_comment(text: &str) -> String {
    let mut out = text.to_string();
    while out.contains("--") {
        out = out.replace("--", "- -");
    }
    out
}

/// The document with `physical` (the template's parameter order) written in. A link that has
/// links fixed to it keeps theirs, and its own `<inertial>` becomes the identified whole less
/// theirs. When that difference is not a physical body (training moved mass the fixed links
/// were given), the fixed links' `<inertial>` become a token body (`Written::MERGED`), each
/// with a comment saying where its mass went, and the link takes the whole less those: the
/// same model either way. The result is
/// read back before it is returned (`check_read_back`): a document that would not give these
/// values on these links is an internal error, never a file.
pub fn export(t: &UrdfTemplate, physical: &[f64]) -> Result<String> {
    let text = &t.doc.urdf;
    let all = elements(text)?;
    let robot_depth = all
        .iter()
        .find(|e| e.tag == "robot")
        .map(|e| e.depth)
        .ok_or_else(|| Error::corrupt("urdf", "no <robot> element".to_string()))?;
    let top = |tag: &str, name: &str| {
        all.iter().position(|e| {
            e.depth == robot_depth + 1 && e.tag == tag && e.name.as_deref() == Some(name)
        })
    };
    let child = |parent: usize, tag: &str| {
        let p = &all[parent];
        let close = p.close?.0;
        all.iter().position(|e| {
            e.depth == p.depth + 1 && e.tag == tag && e.open.0 > p.open.0 && e.open.1 <= close
        })
    };
    let link_at = |name: &str| {
        top("link", name).ok_or_else(|| Error::corrupt("urdf", format!("no link '{name}'")))
    };
    let step = "  ";
    // (start, end, replacement), applied from the end.
    let mut edits: Vec<(usize, usize, String)> = vec![];
    let mut links: HashMap<String, Written> = HashMap::new();
    let mut joints: HashMap<String, ((f64, f64), Option<f64>)> = HashMap::new();
    for (b, body) in t.tree.bodies.iter().enumerate() {
        let identified = t.link_inertial(physical, b);
        // What the reader takes (`tree::link_inertial`): a physical body, or one only just not.
        let readable = |i: &Inertial| i.regularised().theta().is_ok();
        let mut own = identified.minus(&body.inertial.minus(&body.own));
        if !readable(&own) {
            // The fixed links written as token bodies read back so: the link takes the rest.
            let mut tokens = Inertial::ZERO;
            for (name, rot, pos) in &body.fixed {
                if child(link_at(name)?, "inertial").is_some() {
                    tokens = tokens.plus(&Written::MERGED.inertial().transformed(rot, pos));
                }
            }
            own = identified.minus(&tokens);
            if !readable(&own) {
                return Err(Error::FailedPrecondition(format!(
                    "link '{}': the identified body is not physical once the links fixed to \
                     it are written as {MERGED_LINK_MASS} kg tokens",
                    body.link
                )));
            }
            for (name, _, _) in &body.fixed {
                let link = link_at(name)?;
                let Some(i) = child(link, "inertial") else {
                    continue; // no <inertial> reads as massless, as the file had it
                };
                let e = &all[i];
                let indent = indent_at(text, e.open.0);
                let note = format!(
                    "<!-- graybox: identified as part of link '{}' -->\n{indent}",
                    in_comment(&body.link)
                );
                let end = e.close.map_or(e.open.1, |c| c.1);
                edits.push((e.open.0, end, note + &Written::MERGED.xml(indent, step)));
                links.insert(name.clone(), Written::MERGED);
            }
        }
        let own = Written::of(&own);
        links.insert(body.link.clone(), own);
        let link = link_at(&body.link)?;
        let l = &all[link];
        let indent = indent_at(text, l.open.0);
        let inner = format!("{indent}{step}");
        match (child(link, "inertial"), l.close) {
            (Some(i), _) => {
                let e = &all[i];
                let end = e.close.map_or(e.open.1, |c| c.1);
                edits.push((e.open.0, end, own.xml(&inner, step)));
            }
            (None, Some(_)) => {
                let at = l.open.1;
                edits.push((at, at, format!("\n{inner}{}", own.xml(&inner, step))));
            }
            (None, None) => {
                // <link name="x"/> → <link name="x"> <inertial>…</inertial> </link>
                let tag = &text[l.open.0..l.open.1];
                let attributes = tag.strip_suffix("/>").unwrap_or(tag).trim_end();
                edits.push((
                    l.open.0,
                    l.open.1,
                    format!(
                        "{attributes}>\n{inner}{}\n{indent}</link>",
                        own.xml(&inner, step)
                    ),
                ));
            }
        }
        let (damping, friction) = t.joint_dynamics(physical, b);
        let armature = (body.mimic.is_none())
            .then(|| t.armature(physical).get(body.drive.coordinate).copied())
            .flatten();
        joints.insert(body.joint.clone(), ((damping, friction), armature));
        let joint = top("joint", &body.joint)
            .ok_or_else(|| Error::corrupt("urdf", format!("no joint '{}'", body.joint)))?;
        let rotor = armature.map_or(String::new(), |a| format!(" armature=\"{a}\""));
        let dynamics = format!("<dynamics damping=\"{damping}\" friction=\"{friction}\"{rotor}/>");
        let j = &all[joint];
        let close = j
            .close
            .ok_or_else(|| Error::corrupt("urdf", format!("joint '{}' is empty", body.joint)))?;
        match child(joint, "dynamics") {
            Some(d) => {
                let e = &all[d];
                edits.push((e.open.0, e.close.map_or(e.open.1, |c| c.1), dynamics));
            }
            None => {
                let indent = indent_at(text, j.open.0);
                let line = text[..close.0].rfind('\n').map_or(close.0, |k| k + 1);
                let at = if text[line..close.0].trim().is_empty() {
                    line
                } else {
                    close.0
                };
                edits.push((at, at, format!("{indent}{step}{dynamics}\n")));
            }
        }
    }
    edits.sort_by_key(|e| std::cmp::Reverse(e.0));
    let mut out = text.clone();
    for (start, end, with) in edits {
        out.replace_range(start..end, &with);
    }
    check_read_back(t, &out, &links, &joints)?;
    Ok(out)
}

/// The export as the URDF reader reads it: the same robot (a template with the same
/// coordinates and parameters), each link and joint the export wrote with exactly the values
/// written (numbers round-trip), and every other link and joint as the original document
/// has it. An edit in the wrong place, or markup that is not well-formed, fails here.
fn check_read_back(
    t: &UrdfTemplate,
    out: &str,
    links: &HashMap<String, Written>,
    joints: &HashMap<String, ((f64, f64), Option<f64>)>,
) -> Result<()> {
    let wrong = |why: String| {
        Error::Internal(format!(
            "the URDF export of this model does not read back as the model ({why}); \
             no document is given rather than a wrong one"
        ))
    };
    let doc = UrdfDoc {
        urdf: out.to_string(),
        ..t.doc.clone()
    };
    let again =
        UrdfTemplate::from_doc(doc, t.tree.bodies.len()).map_err(|e| wrong(e.to_string()))?;
    let names = |u: &UrdfTemplate| -> Vec<String> {
        u.params().iter().map(|p| p.name.to_string()).collect()
    };
    if again.coordinates() != t.coordinates() || names(&again) != names(t) {
        return Err(wrong("its joints or links differ".into()));
    }
    let read = |s: &str| read::read(s).map_err(|e| wrong(e.to_string()));
    let (before, after) = (read(&t.doc.urdf)?, read(out)?);
    let element_names = |r: &read::Robot| {
        let links = r.links.iter().map(|l| &l.name);
        links
            .chain(r.joints.iter().map(|j| &j.name))
            .cloned()
            .collect::<Vec<_>>()
    };
    if element_names(&before) != element_names(&after) {
        return Err(wrong("its links or joints differ".into()));
    }
    // Bit for bit: the written numbers round-trip, and the others are the same text.
    let bits = |v: [f64; 13]| v.map(f64::to_bits);
    for (was, link) in before.links.iter().zip(&after.links) {
        let want = links
            .get(&link.name)
            .map_or_else(|| read_values(was), Written::values);
        if bits(want) != bits(read_values(link)) {
            return Err(wrong(format!(
                "link '{}' reads back with other values",
                link.name
            )));
        }
    }
    for (was, joint) in before.joints.iter().zip(&after.joints) {
        let got = (joint.dynamics, joint.armature);
        let want =
            (joints.get(&joint.name)).map_or((was.dynamics, was.armature), |&(d, a)| (Some(d), a));
        let bits = |(d, a): JointValues| {
            let d = d.map(|(a, b)| (a.to_bits(), b.to_bits()));
            (d, a.map(f64::to_bits))
        };
        if bits(got) != bits(want) {
            return Err(wrong(format!(
                "joint '{}' reads back with other values",
                joint.name
            )));
        }
    }
    Ok(())
}

/// A joint's `<dynamics>` (damping, friction) and armature as read.
type JointValues = (Option<(f64, f64)>, Option<f64>);

/// A link's `<inertial>` as [`Written::values`] orders it (zeros without one).
fn read_values(link: &read::Link) -> [f64; 13] {
    let i = link.inertial.clone().unwrap_or_default();
    let mut v = [0.0; 13];
    v[..3].copy_from_slice(&i.origin.xyz);
    v[3..6].copy_from_slice(&i.origin.rpy);
    v[6] = i.mass;
    v[7..].copy_from_slice(&i.inertia);
    v
}

#[cfg(test)]
#[path = "export_tests.rs"]
mod tests;
