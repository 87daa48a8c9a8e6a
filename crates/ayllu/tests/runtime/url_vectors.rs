//! The `udp://` URL's shared vectors (`spec/vectors/urls.json`): `UdpConfig::parse` accepts
//! every URL the file says is good, with exactly the values it lists, and refuses every other
//! one with a message that names the bad part. AylluLite's Python and C parsers read the same
//! file (`lite/python/tests/test_url_vectors.py`, `lite/c/tests/test_url.c`), so one
//! `AYLLU_URL` means the same thing to every Ayllu program.

use std::net::SocketAddr;
use std::time::Duration;

use ayllu::UdpConfig;
use serde_json::Value as Json;

fn vectors() -> Vec<Json> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec/vectors/urls.json");
    let text = std::fs::read_to_string(path).expect("spec/vectors/urls.json is readable");
    let doc: Json = serde_json::from_str(&text).expect("urls.json is JSON");
    doc["urls"].as_array().expect("a list of urls").clone()
}

fn addr(v: &Json) -> SocketAddr {
    v.as_str().expect("an address").parse().expect("an IPv4 literal")
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Compare one listed field of a good vector with what the parser made of it.
fn check(name: &str, field: &str, want: &Json, c: &UdpConfig) {
    let n = |v: &Json| v.as_u64().expect("a number");
    match field {
        "ok" => {}
        "bind" => assert_eq!(c.bind, addr(want), "{name}: bind"),
        "team" => assert_eq!(u64::from(c.team), n(want), "{name}: team"),
        "key" => assert_eq!(c.key.map(|k| hex(&k)).as_deref(), want.as_str(), "{name}: key"),
        "peers" => {
            let peers: Vec<SocketAddr> = want.as_array().expect("a list").iter().map(addr).collect();
            assert_eq!(c.peers, peers, "{name}: peers");
        }
        "broadcast" => assert_eq!(c.broadcast, Some(addr(want)), "{name}: broadcast"),
        "groups" => {
            let groups: Vec<(String, SocketAddr)> = want
                .as_array()
                .expect("a list")
                .iter()
                .map(|g| (g[0].as_str().expect("a name").to_owned(), addr(&g[1])))
                .collect();
            assert_eq!(c.groups, groups, "{name}: groups");
        }
        "discovery" => assert_eq!(c.discovery, Some(addr(want)), "{name}: discovery"),
        "ttl" => assert_eq!(u64::from(c.ttl), n(want), "{name}: ttl"),
        "hello_ms" => assert_eq!(c.hello_interval.as_nanos(), n(want) * 1_000_000, "{name}: hello_ms"),
        "mtu" => assert_eq!(c.mtu as u64, n(want), "{name}: mtu"),
        "spin_us" => assert_eq!(c.spin, Duration::from_micros(n(want)), "{name}: spin_us"),
        "name" => assert_eq!(c.name, want.as_str().expect("text"), "{name}: name"),
        "state" => assert_eq!(c.state.as_deref(), Some(std::path::Path::new(want.as_str().expect("a path")))),
        "operator" => {
            assert_eq!(c.operator.as_ref().map(|k| hex(&k.to_bytes())).as_deref(), want.as_str(), "{name}: operator")
        }
        other => panic!("{name}: the vector lists `{other}`, which this test does not know"),
    }
}

#[test]
fn every_url_vector_parses_as_the_file_says() {
    let urls = vectors();
    assert!(urls.len() > 40, "the file holds the whole set");
    // Every disagreement is listed, not just the first.
    let mut wrong = Vec::new();
    for v in &urls {
        let name = v["name"].as_str().expect("a name");
        let url = v["url"].as_str().expect("a url");
        let expect = &v["expect"];
        match (UdpConfig::parse(url), expect["ok"].as_bool().expect("ok")) {
            (Ok(c), true) => {
                for (field, want) in expect.as_object().expect("an object") {
                    check(name, field, want, &c);
                }
            }
            (Err(e), false) => {
                let mentions = expect["mentions"].as_str().expect("what the error names");
                if !e.to_string().contains(mentions) {
                    wrong.push(format!("{name}: `{e}` does not mention `{mentions}`"));
                }
            }
            (Ok(_), false) => wrong.push(format!("{name}: `{url}` was accepted, the vectors refuse it")),
            (Err(e), true) => wrong.push(format!("{name}: `{url}` was refused ({e}), the vectors accept it")),
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}
