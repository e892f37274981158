//! Each multibody algorithm is written once (ARCHITECTURE.md, "One file per concept"): every
//! function of the sources that walks a robot's tree (reads a body's `parent` while going
//! over a `Model`'s bodies) is one of the parts listed here, each with the algorithm it is a
//! pass of. A second ABA, RNEA, CRBA or forward kinematics, in the core or beside it (the
//! service, the C library, the Python module, the lab), fails naming its file and function,
//! and a part that moved or went fails until the list says where it is now.

use std::collections::BTreeSet;
use std::path::Path;

use super::workspace_sources;

const MULTIBODY: &str = "core/src/physics/multibody/";

/// (algorithm, file under `MULTIBODY`, function): the one implementation of each.
const PARTS: &[(&str, &str, &str)] = &[
    ("forward kinematics: placements", "data.rs", "placements"),
    ("forward kinematics: velocities", "data.rs", "motion"),
    (
        "RNEA: accelerations down the tree",
        "data.rs",
        "accelerations",
    ),
    ("RNEA: forces up the tree", "data.rs", "subtree_forces"),
    ("CRBA", "data.rs", "mass"),
    ("ABA", "aba.rs", "aba"),
    ("derivatives of RNEA", "derivatives.rs", "id_derivatives"),
    (
        "derivatives of RNEA: composite variations",
        "derivatives.rs",
        "variations",
    ),
    ("adjoint of RNEA", "adjoint.rs", "id_gradient"),
    // V needs of each placement only gravity in the body's axes and its height along it: a
    // 3-vector a body where forward kinematics composes a 3×3 rotation (a third of the
    // operations on the training tape).
    ("potential energy", "energy.rs", "potential_energy_of"),
];

/// `text` line by line with its comments and the insides of its string and character
/// literals left out: a `//` or a brace in a string is no code (a URL in a message once cut
/// its line, and the brace count went below zero).
fn code_lines(text: &str) -> Vec<String> {
    let mut lines = vec![String::new()];
    let mut in_string = false;
    let mut chars = text.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '\n' => lines.push(String::new()),
            '\\' if in_string => {
                if chars.next() == Some('\n') {
                    lines.push(String::new());
                }
            }
            '"' => {
                in_string = !in_string;
                lines.last_mut().expect("a line").push('"');
            }
            _ if in_string => {}
            '/' if chars.peek() == Some(&'/') => {
                while chars.peek().is_some_and(|&c| c != '\n') {
                    chars.next();
                }
            }
            // A character literal ('{', '\''), not a lifetime ('a).
            '\'' => {
                let ahead: Vec<char> = chars.clone().take(3).collect();
                let skip = match ahead.as_slice() {
                    ['\\', _, '\''] => 3,
                    [_, '\'', ..] => 2,
                    _ => 0,
                };
                for _ in 0..skip {
                    chars.next();
                }
            }
            c => lines.last_mut().expect("a line").push(c),
        }
    }
    lines
}

/// The functions in `text` (by name, with their bodies), found by brace depth: enough for
/// this codebase's formatting (rustfmt's).
fn functions(text: &str) -> Vec<(String, String)> {
    let mut out = vec![];
    let mut open: Vec<(String, usize, String)> = vec![];
    let mut depth = 0usize;
    for code in code_lines(text) {
        let code = code.as_str();
        if let Some(at) = code.find("fn ") {
            let is_item = at == 0 || !code.as_bytes()[at - 1].is_ascii_alphanumeric();
            let name: String = code[at + 3..]
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            if is_item && !name.is_empty() {
                open.push((name, depth, String::new()));
            }
        }
        for (_, _, body) in open.iter_mut() {
            body.push_str(code);
            body.push('\n');
        }
        for c in code.chars() {
            match c {
                '{' => depth += 1,
                '}' => {
                    depth -= 1;
                    while open
                        .last()
                        .is_some_and(|(_, d, b)| *d == depth && b.contains('{'))
                    {
                        let (name, _, body) = open.pop().unwrap();
                        out.push((name, body));
                    }
                }
                _ => {}
            }
        }
        // A declaration without a body (a trait's) ends at its semicolon.
        if code.trim_end().ends_with(';') {
            open.retain(|(_, d, b)| *d != depth || b.contains('{'));
        }
    }
    out
}

fn walks_the_tree(body: &str) -> bool {
    body.contains("model.bodies") && body.contains(".parent")
}

/// `file: function` for every tree walk under the workspace's source directories.
fn tree_walks(root: &Path) -> BTreeSet<(String, String)> {
    let mut walks = BTreeSet::new();
    for (rel, text) in workspace_sources(root) {
        for (name, body) in functions(&text) {
            if walks_the_tree(&body) {
                walks.insert((rel.clone(), name));
            }
        }
    }
    walks
}

#[test]
fn each_multibody_algorithm_is_written_once() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let walks = tree_walks(root);
    let listed: BTreeSet<(String, String)> = PARTS
        .iter()
        .map(|(_, f, name)| (format!("{MULTIBODY}{f}"), name.to_string()))
        .collect();
    let extra: Vec<String> = (walks.difference(&listed))
        .map(|(f, n)| format!("{f}: fn {n}"))
        .collect();
    assert!(
        extra.is_empty(),
        "these walk a robot's tree but are no listed part of an algorithm (a second \
         implementation? call the one in Data, or list a new algorithm in PARTS):\n{}",
        extra.join("\n")
    );
    let gone: Vec<String> = (listed.difference(&walks))
        .map(|(f, n)| format!("{f}: fn {n}"))
        .collect();
    assert!(
        gone.is_empty(),
        "listed parts not found:\n{}",
        gone.join("\n")
    );
    // One definition of each: no name listed twice for one algorithm.
    let algorithms: BTreeSet<&str> = PARTS.iter().map(|(a, _, _)| *a).collect();
    assert_eq!(algorithms.len(), PARTS.len(), "an algorithm listed twice");
}

#[test]
fn the_scanner_sees_a_second_walk() {
    let text = "impl Data {\n    fn mass(&mut self, model: &Model) {\n        for b in \
                &model.bodies {\n            let _ = b.parent;\n        }\n    }\n}\n\
                fn other(x: u8) -> u8 {\n    x\n}\n";
    let found: Vec<(String, bool)> = functions(text)
        .into_iter()
        .map(|(n, b)| (n, walks_the_tree(&b)))
        .collect();
    assert_eq!(
        found,
        vec![("mass".to_string(), true), ("other".to_string(), false)]
    );
}

#[test]
fn the_scanner_reads_no_code_in_strings_and_characters() {
    let text = "fn a() {\n    let url = \"http://x/{\";\n    let c = '}';\n    let s = \"a \\\n\
                {\";\n}\nfn b<'m>(model: &'m Model) {\n    for b in &model.bodies {\n        \
                let _ = b.parent;\n    }\n}\n";
    let found: Vec<(String, bool)> = functions(text)
        .into_iter()
        .map(|(n, b)| (n, walks_the_tree(&b)))
        .collect();
    assert_eq!(
        found,
        vec![("a".to_string(), false), ("b".to_string(), true)]
    );
}
