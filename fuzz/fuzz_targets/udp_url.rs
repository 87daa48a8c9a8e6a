//! `udp://` URLs (command lines, `AYLLU_URL`) into `UdpConfig::parse`: never a panic, whatever
//! the text (a non-ASCII key used to panic the parser, which promises it never does), and a
//! URL that parses gives the same configuration when parsed again.
#![no_main]

use libfuzzer_sys::fuzz_target;

/// Whether parsing `text` could ask DNS (a host name where an address goes): skipped, so the
/// fuzzer stays fast and off the network. Literal addresses exercise the same parser.
fn names_a_host(text: &str) -> bool {
    let rest = text.strip_prefix("udp://").unwrap_or(text);
    let (authority, query) = rest.split_once('?').unwrap_or((rest, ""));
    let addresses = query.split('&').filter_map(|pair| match pair.split_once('=') {
        Some(("peer" | "broadcast" | "discovery", v)) => Some(v),
        Some(("group", v)) => Some(v.split_once('@').map_or(v, |(_, a)| a)),
        _ => None,
    });
    std::iter::once(authority).chain(addresses).any(|a| a.chars().any(|c| c.is_alphabetic()))
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    if names_a_host(text) {
        return;
    }
    if let Ok(config) = ayllu::UdpConfig::parse(text) {
        assert_eq!(ayllu::UdpConfig::parse(text).ok(), Some(config), "parsing is a function of the text");
    }
});
