//! The commit the lab is built from, for the experiments' run.json.

fn main() {
    commit();
}

/// The commit the binary is built from (the workspace's checkout), as `GRAYBOX_COMMIT`
/// ("unknown" outside a git checkout), for the experiments' run.json.
fn commit() {
    let out = std::process::Command::new("git")
        .args(["rev-parse", "HEAD"])
        .output();
    let commit = match out {
        Ok(o) if o.status.success() => String::from_utf8_lossy(&o.stdout).trim().to_string(),
        _ => "unknown".to_string(),
    };
    println!("cargo:rustc-env=GRAYBOX_COMMIT={commit}");
    // A new commit moves HEAD's branch ref (or HEAD itself when detached).
    for path in ["../.git/HEAD", "../.git/refs/heads", "../.git/packed-refs"] {
        if std::path::Path::new(path).exists() {
            println!("cargo:rerun-if-changed={path}");
        }
    }
}
