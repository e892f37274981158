//! Request bodies to the core's types, with errors that name the field and say what to send
//! in words rather than Rust types.

use std::time::{Duration, Instant};

use serde_json::Value;

use crate::error::{Error, Result};

/// A request's `timeout_seconds` as a deadline from now: `default` when absent, at most `max`.
pub fn deadline(timeout_seconds: Option<f64>, default: f64, max: f64) -> Result<Instant> {
    let s = timeout_seconds.unwrap_or(default);
    if !(s.is_finite() && s > 0.0 && s <= max) {
        return Err(Error::invalid(
            "timeout_seconds",
            format!("must be in (0, {max}]"),
        ));
    }
    Ok(Instant::now() + Duration::from_secs_f64(s))
}

/// serde's messages with the Rust type names said in words (`expected usize` → `expected a
/// whole number ≥ 0`), so that an error names what to send, not how it is stored.
pub(super) fn in_words(message: &str) -> String {
    const WORDS: [(&str, &str); 8] = [
        ("expected usize", "expected a whole number ≥ 0"),
        ("expected u64", "expected a whole number ≥ 0"),
        ("expected u32", "expected a whole number ≥ 0"),
        ("expected i64", "expected a whole number"),
        ("expected f64", "expected a number"),
        ("expected f32", "expected a number"),
        ("expected a sequence", "expected a list"),
        ("expected a map", "expected an object"),
    ];
    let mut out = message.to_string();
    for (rust, words) in WORDS {
        out = out.replace(rust, words);
    }
    // "expected struct TrainConfig" names a Rust type: an object is what to send.
    if let Some(at) = out.find("expected struct ") {
        let rest = &out[at + "expected struct ".len()..];
        let name_len = rest
            .find(|c: char| !c.is_alphanumeric() && c != '_')
            .unwrap_or(rest.len());
        out = format!("{}expected an object{}", &out[..at], &rest[name_len..]);
    }
    out
}

/// Parses a JSON body into `T`, naming the field at fault in the error.
pub fn parse_body<T: serde::de::DeserializeOwned>(value: Value) -> Result<T> {
    serde_path_to_error::deserialize(value).map_err(|e| {
        let path = e.path().to_string();
        let message = in_words(&e.into_inner().to_string());
        // serde reports a missing field at its parent: name the field itself.
        let missing = message
            .strip_prefix("missing field `")
            .and_then(|m| m.split('`').next());
        let root = !path.chars().any(|c| c.is_alphanumeric());
        let field = match (root, missing) {
            (true, Some(m)) => m.to_string(),
            (false, Some(m)) => format!("{path}.{m}"),
            (true, None) => "body".to_string(),
            (false, None) => path,
        };
        Error::Unprocessable { field, message }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::jobs::JobRequest;

    #[test]
    fn body_errors_name_the_field() {
        let field = |v: Value| match parse_body::<JobRequest>(v) {
            Err(Error::Unprocessable { field, .. }) => field,
            other => panic!("{other:?}"),
        };
        assert_eq!(field(serde_json::json!({"model": "MVF"})), "dataset_id");
        assert_eq!(
            field(
                serde_json::json!({"dataset_id": "d", "model": "MVF", "training": {"epochs": "x"}})
            ),
            "training.epochs"
        );
    }

    #[test]
    fn body_errors_say_types_in_words() {
        let message = |v: Value| match parse_body::<JobRequest>(v) {
            Err(Error::Unprocessable { message, .. }) => message,
            other => panic!("{other:?}"),
        };
        let m = message(serde_json::json!({"dataset_id": "d", "model": "MVF",
                                           "training": {"epochs": "x"}}));
        assert!(m.contains("a whole number"), "{m}");
        let m = message(serde_json::json!({"dataset_id": "d", "model": "MVF",
                                           "training": {"lr": "fast"}}));
        assert!(m.contains("expected a number"), "{m}");
        let m = message(serde_json::json!({"dataset_id": "d", "model": "MVF", "training": 3}));
        assert!(m.contains("expected an object"), "{m}");
        for rust in ["usize", "f64", "struct", "TrainConfig"] {
            assert!(!m.contains(rust), "{m}");
        }
    }
}
