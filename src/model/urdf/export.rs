//! The identified robot as URDF: the template's own document with each moving link's
//! `<inertial>` and each movable joint's `<dynamics>` rewritten, and every other byte
//! (visuals, collisions, comments, formatting) as it was. A text edit, not a re-serialisation:
//! no XML writer keeps comments and layout.

use super::inertia::Inertial;
use super::template::UrdfTemplate;
use crate::error::{Error, Result};

/// An element of the document: its name, the `name` attribute, and byte spans.
#[derive(Debug, Clone)]
struct Element {
    tag: String,
    name: Option<String>,
    /// The start tag `<tag …>` (or the whole `<tag …/>`).
    open: (usize, usize),
    /// The end tag `</tag>`; None for an empty element.
    close: Option<(usize, usize)>,
    depth: usize,
}

/// Every element of `text` in document order (comments, processing instructions, CDATA and
/// declarations skipped).
fn elements(text: &str) -> Result<Vec<Element>> {
    let b = text.as_bytes();
    let corrupt = |why: &str| Error::corrupt("urdf", why.to_string());
    let mut out: Vec<Element> = vec![];
    let mut open: Vec<usize> = vec![];
    let mut i = 0;
    while let Some(k) = text[i..].find('<') {
        let start = i + k;
        let rest = &text[start..];
        let skip_to = |end: &str| {
            rest.find(end)
                .map(|e| start + e + end.len())
                .ok_or_else(|| corrupt("unterminated markup"))
        };
        if rest.starts_with("<!--") {
            i = skip_to("-->")?;
            continue;
        }
        if rest.starts_with("<![CDATA[") {
            i = skip_to("]]>")?;
            continue;
        }
        if rest.starts_with("<?") {
            i = skip_to("?>")?;
            continue;
        }
        if rest.starts_with("<!") {
            i = skip_to(">")?;
            continue;
        }
        // A tag: to the first '>' outside quotes.
        let mut j = start + 1;
        let mut quote = None;
        while j < b.len() {
            match (quote, b[j]) {
                (None, b'"' | b'\'') => quote = Some(b[j]),
                (Some(q), c) if c == q => quote = None,
                (None, b'>') => break,
                _ => {}
            }
            j += 1;
        }
        if j >= b.len() {
            return Err(corrupt("unterminated tag"));
        }
        let end = j + 1;
        let inner = &text[start + 1..j];
        if let Some(tag) = inner.strip_prefix('/') {
            let tag = tag.trim();
            let e = open.pop().ok_or_else(|| corrupt("unbalanced end tag"))?;
            if out[e].tag != tag {
                return Err(corrupt("mismatched end tag"));
            }
            out[e].close = Some((start, end));
        } else {
            let empty = inner.ends_with('/');
            let body = inner.trim_end_matches('/');
            let tag: String = body.chars().take_while(|c| !c.is_whitespace()).collect();
            out.push(Element {
                name: attribute(body, "name"),
                tag,
                open: (start, end),
                close: None,
                depth: open.len(),
            });
            if !empty {
                open.push(out.len() - 1);
            }
        }
        i = end;
    }
    Ok(out)
}

/// The value of attribute `key` in a start tag's text.
fn attribute(tag: &str, key: &str) -> Option<String> {
    let mut rest = tag;
    while let Some(k) = rest.find(key) {
        let before = rest[..k].chars().last();
        let after = rest[k + key.len()..].trim_start();
        if before.is_some_and(char::is_whitespace)
            && let Some(v) = after.strip_prefix('=')
        {
            let v = v.trim_start();
            let q = v.chars().next()?;
            if q == '"' || q == '\'' {
                let v = &v[1..];
                return v.find(q).map(|e| v[..e].to_string());
            }
        }
        rest = &rest[k + key.len()..];
    }
    None
}

/// The indentation of the line `at` is on.
fn indent_at(text: &str, at: usize) -> &str {
    let line = text[..at].rfind('\n').map_or(0, |k| k + 1);
    let ws = text[line..at].len() - text[line..at].trim_start().len();
    &text[line..line + ws]
}

/// The body's values as an `<inertial>` element: the centre of mass as the origin, the
/// inertia about it in the link's axes, every number in Rust's shortest round-trip form.
fn inertial_xml(body: &Inertial, indent: &str, step: &str) -> String {
    let c = body.com();
    let i = body.inertia_at_com();
    format!(
        "<inertial>\n{indent}{step}<origin xyz=\"{} {} {}\" rpy=\"0 0 0\"/>\n\
         {indent}{step}<mass value=\"{}\"/>\n\
         {indent}{step}<inertia ixx=\"{}\" ixy=\"{}\" ixz=\"{}\" iyy=\"{}\" iyz=\"{}\" izz=\"{}\"/>\n\
         {indent}</inertial>",
        c[0], c[1], c[2], body.mass, i[0][0], i[0][1], i[0][2], i[1][1], i[1][2], i[2][2]
    )
}

/// An `<inertial>` of no mass: a link whose mass the export gives to the body it is fixed to.
fn massless_xml(indent: &str, step: &str) -> String {
    format!(
        "<inertial>\n{indent}{step}<origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>\n\
         {indent}{step}<mass value=\"0\"/>\n\
         {indent}{step}<inertia ixx=\"0\" ixy=\"0\" ixz=\"0\" iyy=\"0\" iyz=\"0\" izz=\"0\"/>\n\
         {indent}</inertial>"
    )
}

/// The document with `physical` (the template's parameter order) written in. A link that has
/// links fixed to it keeps theirs, and its own `<inertial>` becomes the identified whole less
/// theirs. When that difference is not a physical body (training moved mass the fixed links
/// were given), the link takes the whole and the fixed links' `<inertial>` become massless,
/// each with a comment saying where its mass went: the same model either way.
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
    for (b, body) in t.tree.bodies.iter().enumerate() {
        let identified = t.link_inertial(physical, b);
        let mut own = identified.minus(&body.inertial.minus(&body.own));
        if own.theta().is_err() {
            // A massless link reads back as the regularised empty body: leave room for it.
            let empty = Inertial::ZERO.regularised();
            let massless = body
                .fixed
                .iter()
                .fold(Inertial::ZERO, |sum, (_, rot, pos)| {
                    sum.plus(&empty.transformed(rot, pos))
                });
            own = identified.minus(&massless);
            if own.theta().is_err() {
                return Err(Error::FailedPrecondition(format!(
                    "link '{}': the identified body is not physical once the links fixed to \
                     it are written massless",
                    body.link
                )));
            }
            for (name, _, _) in &body.fixed {
                let link = link_at(name)?;
                let Some(i) = child(link, "inertial") else {
                    continue; // no <inertial> reads as massless already
                };
                let e = &all[i];
                let indent = indent_at(text, e.open.0);
                let note = format!(
                    "<!-- graybox: identified as part of link '{}' -->\n{indent}",
                    body.link
                );
                let end = e.close.map_or(e.open.1, |c| c.1);
                edits.push((e.open.0, end, note + &massless_xml(indent, step)));
            }
        }
        let link = link_at(&body.link)?;
        let l = &all[link];
        let indent = indent_at(text, l.open.0);
        let inner = format!("{indent}{step}");
        match (child(link, "inertial"), l.close) {
            (Some(i), _) => {
                let e = &all[i];
                let end = e.close.map_or(e.open.1, |c| c.1);
                edits.push((e.open.0, end, inertial_xml(&own, &inner, step)));
            }
            (None, Some(_)) => {
                let at = l.open.1;
                edits.push((
                    at,
                    at,
                    format!("\n{inner}{}", inertial_xml(&own, &inner, step)),
                ));
            }
            (None, None) => {
                // <link name="x"/> → <link name="x"> <inertial>…</inertial> </link>
                let tag = &text[l.open.0..l.open.1];
                let opened = format!(
                    "{}>",
                    tag.trim_end_matches('>').trim_end_matches('/').trim_end()
                );
                edits.push((
                    l.open.0,
                    l.open.1,
                    format!(
                        "{opened}\n{inner}{}\n{indent}</link>",
                        inertial_xml(&own, &inner, step)
                    ),
                ));
            }
        }
        let (damping, friction) = t.joint_dynamics(physical, b);
        let joint = top("joint", &body.joint)
            .ok_or_else(|| Error::corrupt("urdf", format!("no joint '{}'", body.joint)))?;
        let dynamics = format!("<dynamics damping=\"{damping}\" friction=\"{friction}\"/>");
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
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn elements_skip_comments_and_read_names() {
        let doc = "<?xml version=\"1.0\"?>\n<robot name=\"r\"><!-- <link name=\"no\"/> -->\
                   <link name='a' ><visual/></link><joint name=\"j\" type=\"fixed\"></joint></robot>";
        let e = elements(doc).unwrap();
        let names: Vec<(&str, Option<&str>, usize)> = e
            .iter()
            .map(|e| (e.tag.as_str(), e.name.as_deref(), e.depth))
            .collect();
        assert_eq!(
            names,
            [
                ("robot", Some("r"), 0),
                ("link", Some("a"), 1),
                ("visual", None, 2),
                ("joint", Some("j"), 1)
            ]
        );
    }

    #[test]
    fn attribute_needs_a_whole_key() {
        assert_eq!(
            attribute("joint type=\"x\" name=\"j\"", "name"),
            Some("j".into())
        );
        assert_eq!(attribute("link myname=\"x\"", "name"), None);
    }
}
