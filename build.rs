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
    Ok(())
}
