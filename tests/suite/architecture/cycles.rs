//! No circle of modules inside a layer: `a` uses `b` and `b` (through any others) uses `a`
//! makes both one unit that a reader must hold in mind at once. An edge is any path a file
//! names (`use`, grouped `use`, inline `crate::…`, `super::…`, a child module's name),
//! resolved to the deepest module that exists. A module using its own ancestors (a submodule
//! reading its parent's types) is part of that parent and not counted; test modules
//! (everything after `#[cfg(test)]`) are not counted either.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use super::{collect, module_path};

type Module = Vec<String>;

/// The text of a file up to its test module, with `//` comments removed.
fn production_code(text: &str) -> String {
    let mut out = String::new();
    for line in text.lines() {
        if line.trim_start().starts_with("#[cfg(test)]") {
            break;
        }
        out.push_str(super::code(line));
        out.push('\n');
    }
    out
}

/// Every full path a `use` tree names: `a::{b, c::{d, e}}` → a::b, a::c::d, a::c::e.
fn expand(tree: &str) -> Vec<String> {
    let tree = tree.trim();
    let Some(open) = tree.find('{') else {
        let name = tree.split(" as ").next().unwrap_or("").trim();
        return vec![name.trim_end_matches("::").to_string()];
    };
    let prefix = tree[..open].trim_end_matches("::");
    let inner = &tree[open + 1..tree.rfind('}').unwrap_or(tree.len())];
    let (mut depth, mut start, mut items) = (0, 0, vec![]);
    for (i, c) in inner.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                items.push(&inner[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    items.push(&inner[start..]);
    items
        .into_iter()
        .filter(|s| !s.trim().is_empty())
        .flat_map(expand)
        .map(|rest| match rest.as_str() {
            "self" => prefix.to_string(),
            _ => format!("{prefix}::{rest}"),
        })
        .collect()
}

/// The paths a file names: its `use` trees and the `crate::`/`super::` paths written inline.
fn paths(code: &str) -> Vec<String> {
    let mut out = vec![];
    let mut rest = code;
    while let Some(i) = rest.find("use ") {
        let before = rest[..i].chars().last();
        let after = &rest[i + 4..];
        let end = after.find(';').unwrap_or(after.len());
        if before.is_none_or(|c| !(c.is_alphanumeric() || c == '_')) {
            out.extend(expand(&after[..end]));
        }
        rest = &after[end..];
    }
    for anchor in ["crate::", "super::"] {
        let mut rest = code;
        while let Some(i) = rest.find(anchor) {
            let start = &rest[i..];
            let end = start
                .find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
                .unwrap_or(start.len());
            out.push(start[..end].trim_end_matches("::").to_string());
            rest = &start[end..];
        }
    }
    out
}

/// The module a path names from `module` (`is_dir`: the file is a `mod.rs`), if it is one of
/// `known`: the deepest existing prefix.
fn resolve(module: &Module, path: &str, known: &BTreeSet<Module>) -> Option<Module> {
    let mut segs: Vec<&str> = path.split("::").filter(|s| !s.is_empty()).collect();
    let mut base: Module = match segs.first()? {
        &"crate" => {
            segs.remove(0);
            vec![]
        }
        &"super" | &"self" => {
            let mut base = module.clone();
            while let Some(&s) = segs.first() {
                match s {
                    "super" => base.pop(),
                    "self" => None,
                    _ => break,
                };
                segs.remove(0);
            }
            base
        }
        // A child module of this one by its bare name (`use tensors::…` in `model/mod.rs`).
        first => {
            let mut child = module.clone();
            child.push(first.to_string());
            if !known.contains(&child) {
                return None;
            }
            module.clone()
        }
    };
    let mut found = None;
    for s in segs {
        base.push(s.to_string());
        if known.contains(&base) {
            found = Some(base.clone());
        } else {
            break;
        }
    }
    found
}

/// Edges between modules of one layer, ancestors excluded.
fn edges(src: &Path) -> BTreeMap<Module, BTreeSet<Module>> {
    let mut files = vec![];
    collect(src, &mut files);
    let modules: Vec<(Module, String)> = files
        .iter()
        .map(|f| {
            let text = std::fs::read_to_string(f).unwrap();
            (module_path(f.strip_prefix(src).unwrap()), text)
        })
        .collect();
    let known: BTreeSet<Module> = modules.iter().map(|(m, _)| m.clone()).collect();
    let mut out: BTreeMap<Module, BTreeSet<Module>> = BTreeMap::new();
    for (module, text) in &modules {
        for path in paths(&production_code(text)) {
            let Some(target) = resolve(module, &path, &known) else {
                continue;
            };
            let ancestor = target.len() <= module.len() && module.starts_with(&target);
            if !ancestor && target.first() == module.first() {
                out.entry(module.clone()).or_default().insert(target);
            }
        }
    }
    out
}

/// One circle per module that lies on one, as `a → b → a`.
pub fn circles(src: &Path) -> Vec<String> {
    let graph = edges(src);
    let mut out = BTreeSet::new();
    for start in graph.keys() {
        // Depth-first search on an explicit stack for a path back to `start`.
        let mut stack = vec![(start.clone(), vec![start.clone()])];
        let mut seen = BTreeSet::new();
        while let Some((node, trail)) = stack.pop() {
            for next in graph.get(&node).into_iter().flatten() {
                if next == start {
                    let mut ring: Vec<&Module> = trail.iter().collect();
                    // The same circle from each of its modules: name it from its least one.
                    let least = (0..ring.len()).min_by_key(|&i| ring[i]).unwrap();
                    ring.rotate_left(least);
                    let names: Vec<String> = ring.iter().map(|m| m.join("::")).collect();
                    out.insert(format!("{} → {}", names.join(" → "), names[0]));
                } else if seen.insert(next.clone()) {
                    let mut t = trail.clone();
                    t.push(next.clone());
                    stack.push((next.clone(), t));
                }
            }
        }
    }
    out.into_iter().collect()
}

#[cfg(test)]
mod checker {
    use super::*;

    #[test]
    fn finds_a_circle_through_any_form_of_path() {
        let dir = tempfile::tempdir().unwrap();
        let physics = dir.path().join("physics");
        std::fs::create_dir_all(physics.join("urdf")).unwrap();
        let write = |p: &str, s: &str| std::fs::write(dir.path().join(p), s).unwrap();
        write("physics/mod.rs", "pub mod a;\npub mod b;\npub mod urdf;\n");
        write("physics/a.rs", "use super::{b::B, urdf};\n");
        write(
            "physics/b.rs",
            "pub fn f() -> crate::physics::urdf::template::T {}\n",
        );
        write("physics/urdf/mod.rs", "pub mod template;\n");
        write("physics/urdf/template.rs", "use crate::physics::a;\n");
        write(
            "physics/c.rs",
            "use super::MAX;\n#[cfg(test)]\nuse super::a;\n",
        );
        assert_eq!(
            circles(dir.path()),
            ["physics::a → physics::b → physics::urdf::template → physics::a"]
        );
    }

    #[test]
    fn a_child_using_its_parent_is_no_circle() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(dir.path().join("model/formula")).unwrap();
        let write = |p: &str, s: &str| std::fs::write(dir.path().join(p), s).unwrap();
        write(
            "model/formula/mod.rs",
            "mod parse;\npub use parse::parse;\n",
        );
        write("model/formula/parse.rs", "use super::{Expr, Op};\n");
        assert!(circles(dir.path()).is_empty());
    }
}
