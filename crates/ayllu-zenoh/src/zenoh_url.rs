//! The `zenoh://` URL: how a node joins a Zenoh network, plus the `udp://` settings that keep
//! their meaning (team, key, liveness, names, operator).
//!
//! ```text
//! zenoh://?mode=peer|client&connect=tcp/10.0.0.1:7447&listen=tcp/0.0.0.0:7447&scouting=0|1
//!         &config=PATH&team=7&key=HEX64&hello_ms=1000&mtu=1472&name=robot-1&state=PATH
//!         &operator=HEX64&operator_secret=PATH
//! ```
//!
//! * `mode` (default `peer`): Zenoh's session mode; `client` sessions talk through a router.
//! * `connect`, `listen` (repeatable): Zenoh endpoints (`tcp/ADDR:PORT`, `udp/...`, `tls/...`
//!   with a build that has TLS).
//! * `scouting` (default 1 in peer mode): Zenoh's multicast scouting; 0 keeps the node to the
//!   endpoints given (tests, networks without multicast).
//! * `config=PATH`: a Zenoh JSON5 configuration file (TLS, access control) read first; the
//!   other settings apply over it.
//! * The rest is parsed as a `udp://` URL's query ([`ayllu::UdpConfig`]). `peer=`,
//!   `broadcast=`, `group=`, `discovery=` and `ttl=` name IP addresses and are refused: Zenoh
//!   finds the peers and carries groups (spec/zenoh.md).
//!
//! Parsing never panics; every mistake is an error naming the bad part.

use ayllu::{RuntimeError, UdpConfig};

/// A parsed `zenoh://` URL.
#[derive(Clone, Debug)]
pub struct ZenohUrl {
    /// `peer` or `client`.
    pub mode: String,
    /// Endpoints to connect to.
    pub connect: Vec<String>,
    /// Endpoints to listen on.
    pub listen: Vec<String>,
    /// Whether Zenoh's multicast scouting runs (`None`: Zenoh's default).
    pub scouting: Option<bool>,
    /// A Zenoh configuration file read before the settings above.
    pub config_file: Option<String>,
    /// The Ayllu settings (team, key, liveness, ...), as for `udp://`.
    pub config: UdpConfig,
}

impl ZenohUrl {
    /// Parse a `zenoh://` URL (module docs); the error names the bad part.
    pub fn parse(url: &str) -> Result<ZenohUrl, RuntimeError> {
        let bad = |reason: String| RuntimeError::BadUrl { url: url.to_owned(), reason };
        let rest = url.strip_prefix("zenoh://").ok_or_else(|| bad("expected zenoh://?...".into()))?;
        let (host, query) = rest.split_once('?').unwrap_or((rest, ""));
        if !host.is_empty() {
            return Err(bad(format!(
                "zenoh:// takes no address before `?` (got `{host}`): use connect=tcp/{host} or listen=..."
            )));
        }
        let mut parsed = ZenohUrl {
            mode: "peer".into(),
            connect: Vec::new(),
            listen: Vec::new(),
            scouting: None,
            config_file: None,
            config: UdpConfig::new("0.0.0.0:0".parse().expect("a valid address")),
        };
        let mut ayllu_query = Vec::new();
        for part in query.split('&').filter(|p| !p.is_empty()) {
            let (k, v) = part.split_once('=').unwrap_or((part, ""));
            match k {
                "mode" => match v {
                    "peer" | "client" => parsed.mode = v.to_owned(),
                    _ => return Err(bad(format!("mode must be peer or client, got `{v}`"))),
                },
                "connect" => parsed.connect.push(endpoint(v).map_err(bad)?),
                "listen" => parsed.listen.push(endpoint(v).map_err(bad)?),
                "scouting" => match v {
                    "0" | "false" => parsed.scouting = Some(false),
                    "1" | "true" => parsed.scouting = Some(true),
                    _ => return Err(bad(format!("scouting must be 0 or 1, got `{v}`"))),
                },
                "config" if !v.is_empty() => parsed.config_file = Some(v.to_owned()),
                "peer" | "broadcast" | "group" | "discovery" | "ttl" => {
                    return Err(bad(format!(
                        "`{k}=` names IP addresses, which zenoh:// does not use: Zenoh finds the peers (connect=, \
                         listen=, scouting) and carries every group (spec/zenoh.md)"
                    )))
                }
                _ => ayllu_query.push(part),
            }
        }
        // The Ayllu settings mean what they mean for udp://: one parser for both.
        let as_udp = format!("udp://0.0.0.0:0?{}", ayllu_query.join("&"));
        parsed.config = UdpConfig::parse(&as_udp).map_err(|e| match e {
            RuntimeError::BadUrl { reason, .. } => bad(reason),
            other => other,
        })?;
        Ok(parsed)
    }
}

/// A Zenoh endpoint as `connect=`/`listen=` take it: `PROTO/ADDRESS`, written into a JSON
/// string, so quotes and backslashes are refused.
fn endpoint(v: &str) -> Result<String, String> {
    let ok = v.split_once('/').is_some_and(|(proto, addr)| !proto.is_empty() && !addr.is_empty());
    if !ok || v.contains(['"', '\\']) {
        return Err(format!("expected a Zenoh endpoint like tcp/10.0.0.1:7447, got `{v}`"));
    }
    Ok(v.to_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zenoh_and_ayllu_settings_are_split() {
        let key = "ab".repeat(32);
        let u = ZenohUrl::parse(&format!(
            "zenoh://?mode=client&connect=tcp/10.0.0.1:7447&connect=tcp/10.0.0.2:7447&team=7&key={key}&hello_ms=250"
        ))
        .unwrap();
        assert_eq!(u.mode, "client");
        assert_eq!(u.connect, ["tcp/10.0.0.1:7447", "tcp/10.0.0.2:7447"]);
        assert_eq!(u.config.team, 7);
        assert_eq!(u.config.key, Some([0xab; 32]));
        assert_eq!(u.config.hello_interval, ayllu::Duration::from_millis(250));
    }

    #[test]
    fn mistakes_are_named() {
        for (url, word) in [
            ("udp://0.0.0.0:0", "zenoh://"),
            ("zenoh://10.0.0.1:7447", "connect="),
            ("zenoh://?mode=router", "mode"),
            ("zenoh://?connect=10.0.0.1", "endpoint"),
            ("zenoh://?peer=10.0.0.1:7400", "peer="),
            ("zenoh://?team=x", "team"),
        ] {
            match ZenohUrl::parse(url) {
                Err(RuntimeError::BadUrl { reason, .. }) => assert!(reason.contains(word), "{url}: {reason}"),
                other => panic!("{url}: expected BadUrl, got {other:?}"),
            }
        }
    }
}
