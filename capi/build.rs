//! The shared library's soname carries its ABI version (`GBX_ABI_VERSION` in src/lib.rs, which
//! `tests/c_example.rs` compares with it): a program linked against one ABI looks for
//! libgraybox_c.so.3 and never loads a library of another by accident.
fn main() {
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("linux") {
        println!("cargo:rustc-cdylib-link-arg=-Wl,-soname,libgraybox_c.so.3");
    }
}
