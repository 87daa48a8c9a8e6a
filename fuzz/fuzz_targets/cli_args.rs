//! Fuzz target: arbitrary command lines into the `ayllu` tool's argument parsing.
//!
//! The input is split at NUL bytes into arguments (raw bytes: not necessarily UTF-8, as on a
//! real command line) and parsed as the binary parses them (`ayllu_cli::ArgParser`, clap with
//! every value parser the binary uses; built once and kept between inputs, since building
//! clap's description of every command was most of the cost of an execution). Each argument is also fed to every value parser directly (seconds, rates, node
//! and connection ids, access rules, port paths, sight tables, typed values for `write`).
//! Promises checked: no panic; a number of seconds that parses converts to a duration, and a
//! rate that parses converts to a period (what the commands do with them next: `--for 1e300`,
//! `--timeout 1e300` and `--repeat-hz 1e-300` used to panic there).
#![no_main]

use std::cell::RefCell;
use std::ffi::OsString;
use std::os::unix::ffi::OsStringExt;

use libfuzzer_sys::fuzz_target;

fn check_value(text: &str) {
    if let Ok(x) = ayllu_cli::positive_secs(text) {
        assert!(std::time::Duration::try_from_secs_f64(x).is_ok(), "{text}");
        assert!(ayllu::Duration::try_from_secs_f64(x).is_ok(), "{text}");
    }
    if let Ok(hz) = ayllu_cli::positive_hz(text) {
        assert!(std::time::Duration::try_from_secs_f64(1.0 / hz).is_ok(), "{text}");
        assert!(ayllu::Duration::try_from_hz(hz).is_ok(), "{text}");
    }
    let _ = ayllu_cli::parse_node(text);
    let _ = ayllu_cli::parse_allow(text);
    let _ = ayllu_cli::parse_connection(text);
    let _ = ayllu_cli::parse_port_path(text);
    let _ = ayllu_cli::parse_sight(text);
    for ty in [
        ayllu::ValueType::Bool,
        ayllu::ValueType::Int,
        ayllu::ValueType::Float,
        ayllu::ValueType::Text,
        ayllu::ValueType::Bytes,
        ayllu::ValueType::Vector,
    ] {
        let _ = ayllu_cli::parse_value(ty, text);
    }
}

thread_local! {
    static PARSER: RefCell<ayllu_cli::ArgParser> = RefCell::new(ayllu_cli::ArgParser::new());
}

fuzz_target!(|data: &[u8]| {
    let args: Vec<&[u8]> = data.split(|b| *b == 0).take(32).collect();
    for arg in &args {
        if let Ok(text) = std::str::from_utf8(arg) {
            check_value(text);
        }
    }
    let argv = std::iter::once(OsString::from("ayllu")).chain(args.iter().map(|a| OsString::from_vec(a.to_vec())));
    if let Ok(cli) = PARSER.with(|p| p.borrow_mut().parse(argv)) {
        let _ = format!("{cli:?}");
    }
});
