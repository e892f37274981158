//! Source files stay small enough to read in one sitting: at most [`LIMIT`] lines, so that a
//! file holds one concern and a newcomer can find a thing by its file's name.

use std::path::Path;

use super::collect;

pub const LIMIT: usize = 450;

/// Files allowed over the limit, each with the reason it cannot be split by concern. Only a
/// generated file or one that is a single table belongs here; today there is none.
const ALLOWED: &[&str] = &[];

/// `<label>/<file>: <lines> lines` for each `.rs` file under `src` (named `label`: `src`,
/// `lab/src`) over the limit and not allowed.
pub fn too_long(src: &Path, label: &str) -> Vec<String> {
    let mut files = vec![];
    collect(src, &mut files);
    files
        .iter()
        .filter_map(|f| {
            let rel = f.strip_prefix(src).unwrap().to_string_lossy().into_owned();
            let lines = std::fs::read_to_string(f).unwrap().lines().count();
            (lines > LIMIT && !ALLOWED.contains(&rel.as_str()))
                .then(|| format!("{label}/{rel}: {lines} lines (limit {LIMIT})"))
        })
        .collect()
}

#[cfg(test)]
mod checker {
    use super::*;

    #[test]
    fn names_each_file_over_the_limit() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("train")).unwrap();
        let lines = |n: usize| "// x\n".repeat(n);
        std::fs::write(dir.path().join("train/trainer.rs"), lines(LIMIT + 1)).unwrap();
        std::fs::write(dir.path().join("train/adam.rs"), lines(LIMIT)).unwrap();
        assert_eq!(
            too_long(dir.path(), "src"),
            [format!(
                "src/train/trainer.rs: {} lines (limit {LIMIT})",
                LIMIT + 1
            )]
        );
    }
}
