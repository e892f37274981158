//! The layers of ARCHITECTURE.md, enforced: reads every file under `src/` and `core/src/`
//! (the inference core, whose modules keep their names and layers) and fails on a
//! dependency that points up, naming file and line. It sees `use crate::x`, grouped
//! `use crate::{x, y::z}`, paths written inline without a `use` (`crate::store::JobRow`),
//! and `super::` paths that climb out of a layer. It also fails on a circle of modules inside
//! a layer (`cycles.rs`), on a source file over 450 lines (`sizes.rs`), on a second
//! implementation of a multibody algorithm (`algorithms.rs`) and on a fifth number type
//! (`scalars.rs`).

#[path = "architecture/algorithms.rs"]
mod algorithms;
#[cfg(test)]
#[path = "architecture/checker.rs"]
mod checker;
#[path = "architecture/cycles.rs"]
mod cycles;
#[path = "architecture/scalars.rs"]
mod scalars;
#[path = "architecture/sizes.rs"]
mod sizes;

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// Whether a file of `layer` may import the top-level module `dep`.
fn may_import(layer: &str, dep: &str) -> bool {
    match layer {
        // The mechanics stand on these alone: no Burn (`backend`, and the `burn` crate, checked
        // by `the_core_is_free_of_burn`), no dataset, no record; `simd`'s kernels are plain
        // math on slices (the tape's tanh); `arena` the per-call scratch their vectors live in.
        // `linalg`, written over their numbers, stands beside.
        "physics" => [
            "error", "rng", "names", "simd", "arena", "linalg", "physics",
        ]
        .contains(&dep),
        "linalg" => [
            "error", "rng", "names", "simd", "arena", "physics", "linalg",
        ]
        .contains(&dep),
        _ => !forbidden(layer).contains(&dep),
    }
}

/// Top-level modules each layer must not import. Layers not listed (cli, service and the
/// crate root) may import anything; the lab (`lab/`) is another crate and sees only what the
/// library makes public.
fn forbidden(layer: &str) -> &'static [&'static str] {
    const ABOVE_GROUND: &[&str] = &[
        "physics", "model", "infer", "control", "sim", "train", "store", "app", "worker", "api",
        "cli", "service",
    ];
    match layer {
        "error" | "rng" | "backoff" | "pem" | "names" | "arena" | "array" | "backend" | "simd"
        | "data" | "records" => ABOVE_GROUND,
        "model" | "infer" | "control" | "sim" => {
            &["train", "app", "store", "worker", "api", "cli", "service"]
        }
        "train" => &["app", "store", "worker", "api", "cli", "service"],
        "store" => &["app", "worker", "api", "cli", "service"],
        "app" => &["worker", "api", "cli", "service"],
        "worker" => &["api", "cli"],
        "api" => &["store", "worker"],
        _ => &[],
    }
}

/// The module path of a source file: `src/app/jobs.rs` → [app, jobs], `src/app/mod.rs` →
/// [app], `src/sim.rs` → [sim], `src/lib.rs` → [].
fn module_path(rel: &Path) -> Vec<String> {
    let mut parts: Vec<String> = rel
        .iter()
        .map(|p| p.to_string_lossy().into_owned())
        .collect();
    let file = parts.pop().unwrap_or_default();
    let stem = file.trim_end_matches(".rs");
    if !matches!(stem, "mod" | "lib" | "main") {
        parts.push(stem.to_string());
    }
    parts
}

/// The code of a line without its `//` comment (string literals are rare enough in `use`
/// positions that a `//` inside one is not worth a lexer).
fn code(line: &str) -> &str {
    line.find("//").map_or(line, |i| &line[..i])
}

fn ident(s: &str) -> &str {
    let end = s
        .find(|c: char| !(c.is_alphanumeric() || c == '_'))
        .unwrap_or(s.len());
    &s[..end]
}

/// The names after `{` of a grouped path, at brace depth one: `{x, y::z, w::{a}}` → x, y, w.
fn grouped(s: &str) -> Vec<&str> {
    let (mut depth, mut start, mut out) = (0, 1, vec![]);
    for (i, c) in s.char_indices() {
        match c {
            '{' => depth += 1,
            '}' | ',' if depth == 1 => {
                let name = ident(s[start..i].trim_start());
                if !name.is_empty() {
                    out.push(name);
                }
                start = i + 1;
                if c == '}' {
                    return out;
                }
            }
            '}' => depth -= 1,
            _ => {}
        }
    }
    out
}

/// Top-level modules a line of the file at `module` refers to.
fn deps_of_line<'a>(module: &[String], line: &'a str) -> Vec<&'a str> {
    refs_of_line(module, line, &[])
}

/// The modules directly inside `within` (a path from the crate root: `[]` for top-level
/// modules, `["physics"]` for those of `physics`) that a line of the file at `module` refers
/// to: `crate::<within>::x`, grouped `crate::<within>::{x, y}`, and `super::` paths that climb
/// to `within` itself.
fn refs_of_line<'a>(module: &[String], line: &'a str, within: &[&str]) -> Vec<&'a str> {
    let line = code(line);
    let prefix: String = ["crate"]
        .iter()
        .chain(within)
        .map(|p| format!("{p}::"))
        .collect();
    let mut out = vec![];
    let mut rest = line;
    while let Some(i) = rest.find(prefix.as_str()) {
        let before = rest[..i].chars().last();
        let after = &rest[i + prefix.len()..];
        rest = after;
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == '$') {
            continue; // `$crate::`, `my_crate::`
        }
        if after.starts_with('{') {
            out.extend(grouped(after));
        } else {
            out.push(ident(after));
        }
    }
    let mut rest = line;
    while let Some(i) = rest.find("super::") {
        let before = rest[..i].chars().last();
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
            rest = &rest[i + "super::".len()..];
            continue; // the middle of a `super::super::` chain, counted from its start
        }
        let mut after = &rest[i..];
        let mut ups = 0;
        while let Some(a) = after.strip_prefix("super::") {
            ups += 1;
            after = a;
        }
        rest = after;
        let lands = ups + within.len();
        let climbs_to = if within.is_empty() {
            lands >= module.len()
        } else {
            lands == module.len()
        };
        if climbs_to {
            if after.starts_with('{') {
                out.extend(grouped(after));
            } else {
                out.push(ident(after));
            }
        }
    }
    out.retain(|d| !d.is_empty() && *d != "self" && *d != "super");
    out
}

/// What parts of the core may use of the mechanics (`physics::x`). `physics::multibody`, the
/// rigid-body algorithms built once from any source: its numbers and the manipulator
/// equation's linear algebra, never a producer (`urdf`), a template or the assembly, which
/// stand on it instead. `linalg`, which the mechanics use in turn: their numbers alone (dual
/// ones in its tests, to differentiate through it).
const MAY_USE_OF_PHYSICS: [(&[&str], &[&str]); 2] = [
    (
        &["physics", "multibody"],
        &["multibody", "scalar", "dual", "dynamics"],
    ),
    (&["linalg"], &["scalar", "dual"]),
];

/// `file:line: layer imports module` for every forbidden dependency in `src`.
fn violations(src: &Path) -> Vec<String> {
    violations_in(src, "src")
}

/// `violations` of the source tree `src`, named `label` in the messages.
fn violations_in(src: &Path, label: &str) -> Vec<String> {
    let mut files = vec![];
    collect(src, &mut files);
    let mut out = vec![];
    for file in files {
        let rel = file.strip_prefix(src).unwrap();
        let module = module_path(rel);
        let Some(layer) = module.first() else {
            continue;
        };
        let text = std::fs::read_to_string(&file).unwrap();
        for (n, line) in text.lines().enumerate() {
            // The core's store field is crate-visible for the worker; adapters must not use it.
            if layer == "api" && code(line).contains("app.store") {
                out.push(format!(
                    "{label}/{}:{}: `api` must not reach the store through App: {}",
                    rel.display(),
                    n + 1,
                    line.trim()
                ));
            }
            for (part, may_use) in MAY_USE_OF_PHYSICS {
                if module[..module.len().min(part.len())] != part[..] {
                    continue;
                }
                for dep in refs_of_line(&module, line, &["physics"]) {
                    if !may_use.contains(&dep) {
                        out.push(format!(
                            "{label}/{}:{}: `{}` must not import `physics::{dep}`: {}",
                            rel.display(),
                            n + 1,
                            part.join("::"),
                            line.trim()
                        ));
                    }
                }
            }
            let deps: BTreeSet<&str> = deps_of_line(&module, line).into_iter().collect();
            for dep in deps {
                if !may_import(layer, dep) {
                    out.push(format!(
                        "{label}/{}:{}: `{layer}` must not import `{dep}`: {}",
                        rel.display(),
                        n + 1,
                        line.trim()
                    ));
                }
            }
        }
    }
    out
}

/// Every Rust source of the workspace's members (`root` the workspace), as (path relative
/// to `root`, text).
fn workspace_sources(root: &Path) -> Vec<(String, String)> {
    let mut files = vec![];
    for dir in [
        "core/src",
        "src",
        "capi/src",
        "lab/src",
        "clients/native/src",
    ] {
        collect(&root.join(dir), &mut files);
    }
    (files.into_iter())
        .map(|f| {
            let rel = f.strip_prefix(root).unwrap().to_string_lossy().into_owned();
            (rel, std::fs::read_to_string(&f).unwrap())
        })
        .collect()
}

fn collect(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            collect(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

#[test]
fn no_dependency_points_up() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut v = violations(&root.join("src"));
    v.extend(violations_in(&root.join("core/src"), "core/src"));
    assert!(
        v.is_empty(),
        "{} forbidden dependencies (see ARCHITECTURE.md):\n{}",
        v.len(),
        v.join("\n")
    );
}

/// The core names no Burn in any source file or build: training records its mechanics on the
/// host tape (`physics::tape`), so nothing in the core is written for Burn's tensors.
#[test]
fn the_core_is_free_of_burn() {
    let core = Path::new(env!("CARGO_MANIFEST_DIR")).join("core");
    let manifest = std::fs::read_to_string(core.join("Cargo.toml")).unwrap();
    let named: Vec<&str> = (manifest.lines())
        .filter(|l| !l.trim_start().starts_with('#') && l.contains("burn"))
        .collect();
    assert!(named.is_empty(), "core/Cargo.toml names Burn: {named:?}");
    let mut files = vec![];
    collect(&core.join("src"), &mut files);
    let burn: Vec<String> = files
        .iter()
        .flat_map(|f| {
            let text = std::fs::read_to_string(f).unwrap();
            let hits: Vec<String> = text
                .lines()
                .enumerate()
                .filter(|(_, l)| code(l).contains("burn::"))
                .map(|(n, l)| format!("{}:{}: {}", f.display(), n + 1, l.trim()))
                .collect();
            hits
        })
        .collect();
    assert!(burn.is_empty(), "the core uses Burn:\n{}", burn.join("\n"));
}

/// The inference core builds without Burn, an async runtime, a database or an RPC framework
/// (its `sqlx` feature, which the service turns on, is off here), and so do the
/// C library and the Python module built on it alone.
#[test]
fn the_inference_core_and_its_libraries_depend_on_no_service_framework() {
    for package in ["graybox-core", "graybox-c", "graybox-native"] {
        let out = std::process::Command::new(env!("CARGO"))
            .args([
                "tree",
                "-p",
                package,
                "-e",
                "normal",
                "--prefix",
                "none",
                "--offline",
            ])
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let tree = String::from_utf8(out.stdout).unwrap();
        assert!(tree.starts_with(&format!("{package} ")), "{tree}");
        let framework = |l: &&str| {
            let name = l.split(' ').next().unwrap_or("");
            ["burn", "tokio", "sqlx", "tonic"]
                .iter()
                .any(|f| name == *f || name.starts_with(&format!("{f}-")))
        };
        let found: Vec<&str> = tree.lines().filter(framework).collect();
        assert!(found.is_empty(), "{package} depends on {found:?}");
    }
}

#[test]
fn no_circle_of_modules_inside_a_layer() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut c = cycles::circles(&root.join("src"));
    c.extend(cycles::circles(&root.join("core/src")));
    assert!(c.is_empty(), "{} circles:\n{}", c.len(), c.join("\n"));
}

#[test]
fn no_source_file_is_over_the_limit() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut long = sizes::too_long(&root.join("src"), "src");
    long.extend(sizes::too_long(&root.join("lab/src"), "lab/src"));
    long.extend(sizes::too_long(&root.join("core/src"), "core/src"));
    long.extend(sizes::too_long(&root.join("capi/src"), "capi/src"));
    long.extend(sizes::too_long(
        &root.join("clients/native/src"),
        "clients/native/src",
    ));
    assert!(
        long.is_empty(),
        "split these by concern (or, if generated or table-like, list them in \
         sizes::ALLOWED with the reason):\n{}",
        long.join("\n")
    );
}
