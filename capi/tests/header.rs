//! include/graybox.h is what cbindgen makes of src/lib.rs today: a changed signature that
//! was not regenerated fails here. To regenerate: GRAYBOX_WRITE_HEADER=1 cargo test -p
//! graybox-c --release --test header.

use std::path::Path;

#[test]
fn the_committed_header_is_a_fresh_generation() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(dir.join("cbindgen.toml")).unwrap();
    let mut fresh = vec![];
    cbindgen::Builder::new()
        .with_crate(dir)
        .with_config(config)
        .generate()
        .expect("cbindgen reads src/lib.rs")
        .write(&mut fresh);
    let fresh = String::from_utf8(fresh).unwrap();
    let path = dir.join("include/graybox.h");
    if std::env::var("GRAYBOX_WRITE_HEADER").as_deref() == Ok("1") {
        std::fs::write(&path, &fresh).unwrap();
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == fresh,
        "capi/include/graybox.h differs from cbindgen's generation of capi/src/lib.rs; \
         regenerate it with GRAYBOX_WRITE_HEADER=1 cargo test -p graybox-c --release --test header"
    );
}
