//! The one rule for names (datasets, jobs, reports, templates, URDF links and joints),
//! applied wherever a name enters so that every layer, the mechanics included, can use it.

use crate::error::{Error, Result};

/// The longest name, in characters (not bytes).
pub const NAME_MAX: usize = 200;

/// What is wrong with `name` as a name, if anything. Names are shown to people in listings,
/// logs and reports: at most [`NAME_MAX`] characters, and no control characters (NUL, ESC,
/// newlines) or bidirectional overrides, which can make a name display as something it is
/// not.
pub fn name_problem(name: &str) -> Option<String> {
    if name.chars().count() > NAME_MAX {
        return Some(format!("must be at most {NAME_MAX} characters"));
    }
    let bidi = |c: char| matches!(c, '\u{202A}'..='\u{202E}' | '\u{2066}'..='\u{2069}');
    name.chars().find(|&c| c.is_control() || bidi(c)).map(|c| {
        format!(
            "must not contain control or bidirectional-override characters (found U+{:04X})",
            c as u32
        )
    })
}

/// A name a request gives (`?name=`, a dataset's `"name"`): 400 naming "name".
pub fn check_name(name: &str) -> Result<()> {
    name_problem(name).map_or(Ok(()), |m| Err(Error::invalid("name", m)))
}

/// A name a document or file carries: 422 naming `field`.
pub fn check_name_at(field: &str, name: &str) -> Result<()> {
    name_problem(name).map_or(Ok(()), |message| {
        Err(Error::Unprocessable {
            field: field.into(),
            message,
        })
    })
}

/// A name as an error message may quote it: its first 40 characters, escaped (a name that
/// breaks the rule must not reach a log or a terminal as it is).
pub fn quoted_name(name: &str) -> String {
    let head: String = name.chars().take(40).collect();
    let more = if name.chars().nth(40).is_some() {
        "…"
    } else {
        ""
    };
    format!("{}{more}", head.escape_debug())
}
