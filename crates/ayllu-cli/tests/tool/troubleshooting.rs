//! docs/troubleshooting.md cannot fall behind the code: every counter (`DropCause`), every
//! variant of the core's and the runtime's errors, every C status, every Python exception and
//! every message the `ayllu` tool builds itself (`Fail::error`/`Fail::usage` with a literal
//! text) must be explained there. Adding one without a line on that page fails this test.

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn read(path: &str) -> String {
    std::fs::read_to_string(root().join(path)).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// The page, with backticks taken out so messages that contain them compare as text.
fn page() -> String {
    read("docs/troubleshooting.md")
}

/// The variants of `pub enum <name>` in a Rust source file (lines indented four spaces that
/// start with a capital, up to the enum's closing brace).
fn variants(source: &str, name: &str) -> Vec<String> {
    let start = source.find(&format!("pub enum {name} {{")).unwrap_or_else(|| panic!("no enum {name}"));
    let body = &source[start..];
    let body = &body[..body.find("\n}").expect("the enum closes")];
    body.lines()
        .filter_map(|l| l.strip_prefix("    "))
        .filter(|l| l.starts_with(|c: char| c.is_ascii_uppercase()))
        .map(|l| l.split(|c: char| !c.is_ascii_alphanumeric()).next().unwrap().to_owned())
        .collect()
}

fn missing(names: impl IntoIterator<Item = String>, page: &str) -> Vec<String> {
    names.into_iter().filter(|n| !page.contains(&format!("`{n}`"))).collect()
}

#[test]
fn every_drop_cause_is_explained() {
    let page = page();
    let gone = missing(ayllu::DropCause::ALL.iter().map(|c| c.name().to_owned()), &page);
    assert!(gone.is_empty(), "docs/troubleshooting.md does not explain the counters {gone:?}");
}

#[test]
fn every_api_error_is_explained() {
    let page = page();
    let core = variants(&read("crates/ayllu-core/src/error.rs"), "Error");
    let runtime = variants(&read("crates/ayllu/src/error.rs"), "Error");
    assert!(core.len() >= 20 && runtime.len() >= 5, "the enums were found: {core:?} {runtime:?}");
    let gone = missing(core.into_iter().chain(runtime), &page);
    assert!(gone.is_empty(), "docs/troubleshooting.md does not explain the errors {gone:?}");
}

#[test]
fn every_c_status_and_python_exception_is_explained() {
    let page = page();
    let header = read("crates/ayllu-c/include/ayllu_sys.h");
    let statuses: Vec<String> = header
        .lines()
        .filter_map(|l| l.trim().strip_suffix(',').or(Some(l.trim())))
        .filter(|l| l.starts_with("AY_OK") || l.starts_with("AY_ERR_"))
        .filter_map(|l| l.split_whitespace().next().map(str::to_owned))
        .filter(|s| s.chars().all(|c| c.is_ascii_uppercase() || c == '_'))
        .collect();
    assert!(statuses.len() >= 14, "{statuses:?}");
    let stubs = read("crates/ayllu-py/python/ayllu/_native.pyi");
    let exceptions: Vec<String> = stubs
        .lines()
        .filter_map(|l| l.strip_prefix("class "))
        .filter(|l| l.contains("Error(") || l.contains("(Exception)"))
        .map(|l| l.split('(').next().unwrap().to_owned())
        .collect();
    assert!(exceptions.len() >= 6, "{exceptions:?}");
    let gone = missing(statuses.into_iter().chain(exceptions), &page);
    assert!(gone.is_empty(), "docs/troubleshooting.md does not explain {gone:?}");
}

/// The longest literal part of a format string (placeholders removed), trimmed of the
/// punctuation that joins it to them.
fn longest_literal(format: &str) -> String {
    let text = format.replace("{{", "\u{1}").replace("}}", "\u{2}");
    let mut parts = Vec::new();
    let mut rest = text.as_str();
    while let Some(open) = rest.find('{') {
        parts.push(&rest[..open]);
        rest = rest[open..].find('}').map_or("", |close| &rest[open + close + 1..]);
    }
    parts.push(rest);
    let best = parts.into_iter().max_by_key(|p| p.trim().len()).unwrap_or("");
    best.trim_matches(|c: char| c.is_whitespace() || ":`(".contains(c))
        .replace('\u{1}', "{")
        .replace('\u{2}', "}")
        .replace('`', "")
}

/// A Rust string literal's text up to its closing quote: escapes undone, and a backslash at the
/// end of a line joining it to the next line's text (Rust's string continuation).
fn unescape(literal: &str) -> String {
    let mut out = String::new();
    let mut chars = literal.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '"' => return out,
            '\\' => match chars.next() {
                Some('\n') => {
                    while chars.peek().is_some_and(|c| c.is_whitespace()) {
                        chars.next();
                    }
                }
                Some('n') => out.push('\n'),
                Some(other) => out.push(other),
                None => break,
            },
            c => out.push(c),
        }
    }
    panic!("a string literal that does not close: {literal:.60}")
}

/// Every `Fail::error(...)`/`Fail::usage(...)` of the tool whose message starts with a string
/// literal (directly or through `format!`): (file, literal).
fn tool_messages() -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut dirs = vec![root().join("crates/ayllu-cli/src")];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                dirs.push(path);
                continue;
            }
            if path.extension().is_none_or(|e| e != "rs") {
                continue;
            }
            let source = std::fs::read_to_string(&path).unwrap();
            for (at, _) in source.match_indices("Fail::") {
                let call = &source[at..];
                let Some(open) = call.find('(') else { continue };
                let ctor = &call["Fail::".len()..open];
                if ctor != "error" && ctor != "usage" {
                    continue;
                }
                let mut args = call[open + 1..].trim_start();
                if let Some(inner) = args.strip_prefix("format!(") {
                    args = inner.trim_start();
                }
                let Some(literal) = args.strip_prefix('"') else { continue };
                let name = path.file_name().unwrap().to_string_lossy().into_owned();
                out.push((name, longest_literal(&unescape(literal))));
            }
        }
    }
    out
}

#[test]
fn every_message_of_the_tool_is_explained() {
    let page = page().replace('`', "");
    let messages = tool_messages();
    assert!(messages.len() >= 20, "the tool's messages were found: {messages:?}");
    let gone: Vec<_> = messages.into_iter().filter(|(_, m)| m.len() >= 8 && !page.contains(m.as_str())).collect();
    assert!(gone.is_empty(), "docs/troubleshooting.md does not explain these messages of the tool: {gone:?}");
}

#[test]
fn the_literal_of_a_format_string_is_what_the_page_is_searched_for() {
    assert_eq!(longest_literal("--udp must be a udp:// URL, got `{}`"), "--udp must be a udp:// URL, got");
    assert_eq!(longest_literal("{what}: interrupted before {node} answered"), "interrupted before");
    assert_eq!(
        longest_literal("one --udp URL for {n} bodies must use `{{i}}` or bind port 0"),
        "bodies must use {i} or bind port 0"
    );
    assert_eq!(unescape("a \\\n     b \\\"c\\\" d\" rest"), "a b \"c\" d");
}

#[path = "../../../../examples/tutorial/02_subsumption/main.rs"]
#[allow(dead_code)] // its `main` is for `cargo run --example`
mod subsumption;

#[test]
fn the_why_the_page_shows_is_what_tutorial_2_prints() {
    let page = page();
    let start = page.find("\n```text\n").expect("the page shows a why") + "\n```text\n".len();
    let shown = &page[start..start + page[start..].find("```").unwrap()];
    let out = subsumption::run().unwrap();
    assert!(out.contains(shown), "docs/troubleshooting.md's why is not what tutorial 2 prints now:\n{out}");
}
