//! The shared library's SONAME on Linux: `libayllu.so.<major>`, the name `make install` gives
//! it (with `libayllu.so` linking to it), so programs record a name that survives compatible
//! upgrades.

fn main() {
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("linux") {
        let major = std::env::var("CARGO_PKG_VERSION_MAJOR").unwrap_or_else(|_| "0".to_owned());
        println!("cargo:rustc-cdylib-link-arg=-Wl,-soname,libayllu.so.{major}");
    }
    println!("cargo:rerun-if-changed=build.rs");
}
