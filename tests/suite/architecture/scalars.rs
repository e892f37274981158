//! At most four number types implement `Scalar`, each in a file ARCHITECTURE.md names with why
//! it exists ("## Number types"): another forward-mode type, or a second home for one, fails
//! naming its file and line, and a listed file that lost its implementation fails too.

use std::collections::BTreeSet;
use std::path::Path;

use super::workspace_sources;

/// The most number types the mechanics are written for.
const MOST: usize = 4;

/// The files the table under ARCHITECTURE.md's "## Number types" names (its second column).
fn listed(architecture: &str) -> BTreeSet<String> {
    let section = architecture
        .split("\n## ")
        .find(|s| s.starts_with("Number types"))
        .expect("ARCHITECTURE.md has a \"## Number types\" section");
    section
        .lines()
        .filter(|l| l.starts_with("| `"))
        .filter_map(|l| l.split('|').nth(2))
        .map(|cell| cell.trim().trim_matches('`').to_string())
        .collect()
}

/// `file:line` of every `impl … Scalar for` in the workspace's sources.
fn implementations(root: &Path) -> Vec<(String, usize)> {
    let mut out = vec![];
    for (rel, text) in workspace_sources(root) {
        for (i, line) in text.lines().enumerate() {
            let code = line.split("//").next().unwrap_or("").trim_start();
            if code.starts_with("impl") && code.contains(" Scalar for ") {
                out.push((rel.clone(), i + 1));
            }
        }
    }
    out
}

#[test]
fn at_most_four_number_types_each_where_architecture_says() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let architecture = std::fs::read_to_string(root.join("ARCHITECTURE.md")).unwrap();
    let files = listed(&architecture);
    assert!(
        files.len() <= MOST,
        "ARCHITECTURE.md lists {} number types, at most {MOST}: {files:?}",
        files.len()
    );
    let found = implementations(root);
    let stray: Vec<String> = (found.iter())
        .filter(|(f, _)| !files.contains(f))
        .map(|(f, l)| format!("{f}:{l}"))
        .collect();
    assert!(
        stray.is_empty(),
        "`Scalar` implemented outside the files ARCHITECTURE.md names under \"Number types\" \
         (a new number type? merge it into one of those, or say there why it must exist):\n{}",
        stray.join("\n")
    );
    assert!(
        found.len() <= MOST,
        "{} implementations of `Scalar`, at most {MOST}: {found:?}",
        found.len()
    );
    let homes: BTreeSet<&String> = found.iter().map(|(f, _)| f).collect();
    let empty: Vec<&String> = files.iter().filter(|f| !homes.contains(f)).collect();
    assert!(
        empty.is_empty(),
        "ARCHITECTURE.md names these as a number type's home, but they implement no `Scalar`: \
         {empty:?}"
    );
}
