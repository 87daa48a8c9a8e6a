//! `include/ayllu_sys.h` is what cbindgen makes of this crate, byte for byte: the committed
//! header cannot drift from the code. `AYLLU_BLESS=1` rewrites it instead of failing.

use std::path::Path;

#[test]
fn the_committed_header_is_what_cbindgen_generates() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(dir.join("cbindgen.toml")).expect("cbindgen.toml");
    let mut generated = Vec::new();
    cbindgen::Builder::new()
        .with_crate(dir)
        .with_config(config)
        .generate()
        .expect("cbindgen generates the header")
        .write(&mut generated);
    let path = dir.join("include/ayllu_sys.h");
    if std::env::var_os("AYLLU_BLESS").is_some() {
        std::fs::write(&path, &generated).expect("write the header");
        return;
    }
    let committed = std::fs::read(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "include/ayllu_sys.h differs from what cbindgen generates from the code: run \
         `AYLLU_BLESS=1 cargo test -p ayllu-c --test library header` and commit the header"
    );
}
