//! A model file proves it is whole: an edit of what defines its answers is refused, and so is
//! a member count that disagrees with its report or the training limit, whether or not the
//! file has a checksum; a file from before checksums loads with a warning; a written file
//! reads back whatever its JSON's formatting.

use std::path::Path;

use serde_json::{Value, json};

use super::checksum;
use super::{FORMAT, MAX_MEMBERS, ModelFile, UNCHECKED};
use crate::error::Error;
use crate::model::NamedArray;
use crate::physics::integrator::Integrator;
use crate::physics::templates::Template;

/// A compatibility fixture's bytes: a file an earlier graybox wrote, without a checksum.
fn fixture(name: &str) -> Vec<u8> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/compat");
    std::fs::read(dir.join(format!("{name}.gbx"))).unwrap()
}

/// The fixture as this graybox writes it: with its checksum.
fn written(name: &str) -> Vec<u8> {
    ModelFile::from_bytes(&fixture(name))
        .unwrap()
        .to_bytes()
        .unwrap()
}

fn json_of(bytes: &[u8]) -> Value {
    serde_json::from_slice(bytes).unwrap()
}

fn bytes_of(v: &Value) -> Vec<u8> {
    serde_json::to_vec(v).unwrap()
}

/// The error reading `bytes` gives: an invalid argument naming `field`, its message holding
/// every one of `words`.
fn refused(bytes: &[u8], field: &str, words: &[&str]) {
    match ModelFile::from_bytes(bytes) {
        Err(Error::Invalid { field: f, message }) => {
            assert_eq!(f, field, "{message}");
            for w in words {
                assert!(message.contains(w), "'{w}' not in: {message}");
            }
        }
        Err(e) => panic!("expected an invalid {field}, got {e}"),
        Ok(f) => panic!("an edited file loaded ({} members)", f.member_count()),
    }
}

/// An ensemble of `k` true double pendulums whose first mass differs member by member.
fn ensemble(k: usize) -> ModelFile {
    let t = Template::DoublePendulum;
    let files = (0..k)
        .map(|i| {
            let mut values = t.defaults();
            values[0] *= 1.0 + 0.01 * i as f64;
            ModelFile::from_template(&t, &values, 0.01, Integrator::Rk4).unwrap()
        })
        .collect();
    ModelFile::ensemble(files, None)
}

#[test]
fn one_changed_digit_of_a_weight_is_refused() {
    let text = String::from_utf8(written("mvf")).unwrap();
    assert!(ModelFile::from_bytes(text.as_bytes()).is_ok());
    // The first value of the first array that has a decimal point: its first decimal changed.
    let values = text.find("\"values\":[").unwrap() + "\"values\":[".len();
    let end = values + text[values..].find(']').unwrap();
    let (start, number) = (text[values..end].split(','))
        .scan(values, |at, n| {
            let here = *at;
            *at += n.len() + 1;
            Some((here, n))
        })
        .find(|(_, n)| n.contains('.'))
        .unwrap();
    let digit = start + number.find('.').unwrap() + 1;
    let old = text.as_bytes()[digit];
    let mut edited = text.clone().into_bytes();
    edited[digit] = if old == b'9' { b'0' } else { old + 1 };
    refused(&edited, "checksum", &["edited"]);
}

#[test]
fn an_edited_config_is_refused_and_an_edited_report_is_not_an_edit_of_the_model() {
    let mut v = json_of(&written("wb"));
    v["config"]["dt"] = json!(0.02);
    refused(&bytes_of(&v), "checksum", &["config"]);

    // The report describes the model and changes none of its answers.
    let mut v = json_of(&written("wb"));
    v["report"]["model"] = json!("renamed");
    let file = ModelFile::from_bytes(&bytes_of(&v)).unwrap();
    assert!(file.unchecked_warning().is_none());
}

#[test]
fn members_removed_are_refused_with_or_without_a_checksum() {
    for bytes in [fixture("wb-x3"), written("wb-x3")] {
        let mut v = json_of(&bytes);
        v["members"].as_array_mut().unwrap().pop();
        refused(&bytes_of(&v), "members", &["2 member(s)", "lists 3"]);
    }
}

/// Deleted `members` must not leave one model answering with no spread, as if certain.
#[test]
fn an_ensemble_without_its_members_is_refused() {
    for bytes in [fixture("wb-x3"), written("wb-x3")] {
        let v = json_of(&bytes);
        let mut gone = v.clone();
        gone.as_object_mut().unwrap().remove("members");
        refused(&bytes_of(&gone), "members", &["lists 3"]);
        // With the report that lists them gone too, the format still says ensemble.
        let mut bare = gone.clone();
        for key in ["report", "checksum"] {
            bare.as_object_mut().unwrap().remove(key);
        }
        refused(
            &bytes_of(&bare),
            "members",
            &["graybox.model/3", "no spread"],
        );
        // As a single model's format, with the report that lists three.
        let mut single = gone.clone();
        single["format"] = json!(FORMAT);
        refused(&bytes_of(&single), "members", &["1 member(s)", "lists 3"]);
    }
}

#[test]
fn more_members_than_training_allows_are_refused() {
    let at_limit = ensemble(MAX_MEMBERS);
    let back = ModelFile::from_bytes(&at_limit.to_bytes().unwrap()).unwrap();
    assert_eq!(back.member_count(), MAX_MEMBERS);

    let over = ensemble(MAX_MEMBERS + 1);
    assert!(matches!(over.to_bytes(), Err(Error::Invalid { field, .. }) if field == "members"));
    // Written by hand (no checksum), as a 201-member file was.
    let text = serde_json::to_vec(&over).unwrap();
    refused(&text, "members", &["33 members", "at most 32"]);
}

#[test]
fn a_file_from_before_checksums_loads_with_a_warning() {
    for name in ["mvf", "wb", "naive", "wb-x3"] {
        let file = ModelFile::from_bytes(&fixture(name)).unwrap();
        let w = file.unchecked_warning().expect("a warning");
        assert_eq!(
            (w.code.as_str(), w.field.as_deref()),
            (UNCHECKED, Some("checksum"))
        );
        assert!(w.message.contains("no checksum"), "{}", w.message);
        // A member of it is no better proven.
        assert!(file.member(0).unchecked_warning().is_some());
    }
}

/// A written file carries its checksum and reads back exactly, also after another tool
/// re-formats its JSON: keys sorted, pretty-printed, a number spelled otherwise.
#[test]
fn a_written_file_round_trips_whatever_its_json_formatting() {
    for file in [ModelFile::from_bytes(&fixture("mvf")).unwrap(), ensemble(3)] {
        let bytes = file.to_bytes().unwrap();
        let v = json_of(&bytes);
        assert!(
            v["checksum"].as_str().unwrap().starts_with("sha256:"),
            "{}",
            v["checksum"]
        );
        let back = ModelFile::from_bytes(&bytes).unwrap();
        assert!(back.unchecked_warning().is_none());
        assert_eq!(back.params, file.params);
        assert_eq!(back.members, file.members);
        assert_eq!(back.to_bytes().unwrap(), bytes, "written again alike");

        let pretty = serde_json::to_vec_pretty(&v).unwrap();
        let dt = format!(
            "\"dt\": {}",
            serde_json::to_string(&file.config.dt).unwrap()
        );
        let pretty = String::from_utf8(pretty).unwrap();
        assert!(pretty.contains(&dt), "{dt}");
        let respelled = pretty.replacen(&dt, &format!("\"dt\": {:e}", file.config.dt), 1);
        assert_ne!(respelled, pretty);
        for text in [pretty, respelled] {
            let again = ModelFile::from_bytes(text.as_bytes()).unwrap();
            assert!(again.unchecked_warning().is_none());
            assert_eq!(again.params, file.params);
        }
    }
}

/// The encoding is the file format: a change to it would refuse every file written before.
/// The value was computed apart, by a Python transcription of docs/model-file.md's encoding.
#[test]
fn the_checksum_of_a_known_file_is_pinned() {
    let config = json!({"n": 1, "dt": 0.01, "spec": {"kind": "naive"}, "periodic": []});
    let arrays = [NamedArray {
        name: "naive.layers.0.bias".into(),
        shape: vec![2],
        values: vec![0.5, -0.0],
    }];
    let sum = checksum::of(FORMAT, &config, &[&arrays[..]]);
    assert_eq!(
        sum,
        "sha256:8bc1da938acb6af77e7e2866d35f247feedec4535a8c5fd26e45c473b3aff063"
    );
    // Key order and a number's spelling are formatting, not content.
    let respelled: Value = serde_json::from_str(
        r#"{"periodic": [], "spec": {"kind": "naive"}, "dt": 1e-2, "n": 1.0}"#,
    )
    .unwrap();
    assert_eq!(checksum::of(FORMAT, &respelled, &[&arrays[..]]), sum);
    // Every value's bits count, the sign of a zero too.
    let mut other = arrays.clone();
    other[0].values[1] = 0.0;
    assert_ne!(checksum::of(FORMAT, &config, &[&other[..]]), sum);
}
