//! Generates the gRPC code from `proto/` at build time with a vendored protoc (a fresh
//! machine has none).

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let protoc = protoc_bin_vendored::protoc_bin_path()?;
    // SAFETY: build scripts are single-threaded; prost-build reads PROTOC from the environment.
    unsafe { std::env::set_var("PROTOC", protoc) };
    let out = std::path::PathBuf::from(std::env::var("OUT_DIR")?);
    tonic_prost_build::configure()
        .file_descriptor_set_path(out.join("graybox_descriptor.bin"))
        .compile_protos(&["proto/graybox/v1/dynamics.proto"], &["proto"])?;
    println!("cargo:rerun-if-changed=proto");
    commit();
    Ok(())
}

/// The commit the binary is built from, as `GRAYBOX_COMMIT` ("unknown" outside a git
/// checkout, e.g. a Docker build context), for the experiments' run.json.
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
    for path in [".git/HEAD", ".git/refs/heads", ".git/packed-refs"] {
        if std::path::Path::new(path).exists() {
            println!("cargo:rerun-if-changed={path}");
        }
    }
}
