//! `udp://` URLs (command lines, `AYLLU_URL`) into `UdpConfig::parse`: never a panic, whatever
//! the text (a non-ASCII key used to panic the parser, which promises it never does), and a
//! URL that parses gives the same configuration when parsed again.
#![no_main]

use std::net::{IpAddr, SocketAddr};

use libfuzzer_sys::fuzz_target;

/// Whether resolving `addr` would ask the system resolver (and so maybe DNS): the standard
/// library does unless the text is a literal socket address, or has no `:PORT` to split off.
/// Such inputs are skipped so the fuzzer stays fast and sends nothing off the machine; the
/// parser's own code runs the same on literal addresses. (Skipping only text with letters is
/// not enough: `1..2:80` goes to the resolver too, and that made this target slow.)
fn asks_resolver(addr: &str) -> bool {
    addr.parse::<SocketAddr>().is_err()
        && addr
            .rsplit_once(':')
            .is_some_and(|(host, port)| port.parse::<u16>().is_ok() && host.parse::<IpAddr>().is_err())
}

/// Whether parsing `text` could ask the resolver for any address in it.
fn names_a_host(text: &str) -> bool {
    let rest = text.strip_prefix("udp://").unwrap_or(text);
    let (authority, query) = rest.split_once('?').unwrap_or((rest, ""));
    let addresses = query.split('&').filter_map(|pair| match pair.split_once('=') {
        Some(("peer" | "broadcast" | "discovery", v)) => Some(v),
        Some(("group", v)) => Some(v.split_once('@').map_or(v, |(_, a)| a)),
        _ => None,
    });
    std::iter::once(authority).chain(addresses).any(asks_resolver)
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
