//! One pass over a URDF's XML before anything builds a tree of it. The URDF reader recurses
//! once per level of nesting (while it builds its element tree, prints it again and
//! deserializes it), so the nesting and the size are bounded here first, by a reader that
//! keeps nothing (quick-xml) and says where a problem is.

use quick_xml::Reader;
use quick_xml::events::Event;

use crate::error::{Error, Result};

/// Nesting of elements: a URDF needs five (robot, link, visual, geometry, mesh), simulator
/// extensions a few more.
pub const MAX_DEPTH: usize = 32;

/// Elements of one document: a 30-joint robot with meshes, collisions and transmissions has
/// a few thousand.
pub const MAX_ELEMENTS: usize = 100_000;

fn bad(message: impl Into<String>) -> Error {
    Error::Unprocessable {
        field: "urdf".into(),
        message: message.into(),
    }
}

/// "line L, column C" (1-based, columns in characters) of a byte offset in `text`.
pub fn line_col(text: &str, offset: usize) -> String {
    let before = &text[..text.floor_char_boundary(offset.min(text.len()))];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    format!("line {line}, column {column}")
}

/// Well-formed XML without a DTD, nested at most [`MAX_DEPTH`] deep, with at most
/// [`MAX_ELEMENTS`] elements and at most `max_dof` movable joints.
pub fn precheck(text: &str, max_dof: usize) -> Result<()> {
    let mut reader = Reader::from_str(text);
    let (mut depth, mut elements, mut movable) = (0usize, 0usize, 0usize);
    loop {
        let at = reader.buffer_position() as usize;
        let event = reader.read_event().map_err(|e| {
            let where_ = line_col(text, reader.error_position() as usize);
            bad(format!("not XML: {e} at {where_}"))
        })?;
        let (start, opens) = match event {
            Event::Start(s) => (s, true),
            Event::Empty(s) => (s, false),
            Event::End(_) => {
                depth = depth.saturating_sub(1);
                continue;
            }
            Event::DocType(_) => {
                return Err(bad(format!(
                    "a URDF has no document type declaration (entities are not expanded); \
                     remove the <!DOCTYPE …> at {}",
                    line_col(text, at)
                )));
            }
            Event::Eof => break,
            _ => continue,
        };
        elements += 1;
        if elements > MAX_ELEMENTS {
            return Err(bad(format!(
                "more than {MAX_ELEMENTS} elements (the limit) at {}",
                line_col(text, at)
            )));
        }
        if depth >= MAX_DEPTH {
            return Err(bad(format!(
                "elements nested more than {MAX_DEPTH} deep (the limit) at {}",
                line_col(text, at)
            )));
        }
        if depth == 1 && start.name().as_ref() == b"joint" {
            let kind = start
                .try_get_attribute("type")
                .ok()
                .flatten()
                .map(|a| a.value.into_owned());
            if kind.as_deref() != Some(b"fixed") {
                movable += 1;
                if movable > max_dof {
                    return Err(bad(format!(
                        "more than {max_dof} movable joints (--max-dof) at {}",
                        line_col(text, at)
                    )));
                }
            }
        }
        if opens {
            depth += 1;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_count_lines_and_characters() {
        assert_eq!(line_col("<a>\n  <b/>", 6), "line 2, column 3");
        assert_eq!(line_col("θ<", 2), "line 1, column 2");
        assert_eq!(line_col("ab", 99), "line 1, column 3");
    }
}
