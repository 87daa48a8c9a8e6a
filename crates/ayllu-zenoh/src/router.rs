//! A Zenoh router: what joins Ayllu nodes on networks with no route between them
//! (`ayllu-zenoh router`, docs/zenoh.md). No `zenohd` is needed: this is a Zenoh session in
//! router mode, from the same Zenoh crate and version as the nodes, so a stock `zenohd` of that
//! version and this router are interchangeable (same configuration file, same locators).
//!
//! Promises: [`Router::open`] returns once the router listens on every `listen` endpoint (an
//! endpoint Zenoh cannot bind is an error, not a router that silently listens on nothing);
//! [`Router::locators`] names the endpoints as bound, so port 0 in `listen` comes back as the
//! port the system chose (a test or a script reads it back instead of picking a port). The router
//! carries Ayllu's datagrams as opaque payloads: it neither reads nor needs the team key, and
//! cannot forge a datagram that a keyed node would accept (spec/zenoh.md).

use ayllu::RuntimeError;
use zenoh::{Config, Session, Wait};

/// How to start a router: Zenoh endpoints and an optional Zenoh configuration file.
#[derive(Clone, Debug, Default)]
pub struct RouterOptions {
    /// Endpoints to listen on (`tcp/0.0.0.0:7447`, `tls/0.0.0.0:7447`; port 0: the system
    /// chooses). Empty: the configuration file's, or Zenoh's default (`tcp/[::]:7447`).
    pub listen: Vec<String>,
    /// Other routers to connect to (a router per site, joined).
    pub connect: Vec<String>,
    /// A Zenoh JSON5 configuration file (TLS, access control), read first; `listen` and
    /// `connect` apply over it, and the mode is always `router`.
    pub config_file: Option<String>,
    /// Zenoh's multicast scouting (`None`: the file's or Zenoh's default).
    pub scouting: Option<bool>,
}

/// A running Zenoh router; closed when dropped.
pub struct Router {
    session: Session,
}

fn fail(what: &str, e: impl std::fmt::Display) -> RuntimeError {
    RuntimeError::Io { what: what.to_owned(), error: e.to_string() }
}

fn json_list(v: &[String]) -> String {
    serde_json::to_string(v).expect("a list of strings is JSON")
}

impl Router {
    /// Start a router as `options` say.
    pub fn open(options: &RouterOptions) -> Result<Router, RuntimeError> {
        let mut config = match &options.config_file {
            Some(path) => {
                Config::from_file(path).map_err(|e| fail(&format!("reading Zenoh configuration {path}"), e))?
            }
            None => Config::default(),
        };
        let mut set = |key: &str, value: String| {
            config.insert_json5(key, &value).map_err(|e| fail(&format!("Zenoh setting {key}={value}"), e))
        };
        set("mode", "\"router\"".into())?;
        if !options.listen.is_empty() {
            set("listen/endpoints", json_list(&options.listen))?;
        }
        if !options.connect.is_empty() {
            set("connect/endpoints", json_list(&options.connect))?;
        }
        if let Some(on) = options.scouting {
            set("scouting/multicast/enabled", on.to_string())?;
        }
        // A listen endpoint that cannot be bound ends the start (Zenoh's default for routers
        // too, made explicit: a router listening on nothing is worse than no router).
        set("listen/exit_on_failure", "true".into())?;
        // The admin space answers "where do you listen" (the bound ports); zenohd opens it,
        // read-only, by default too.
        set("adminspace/enabled", "true".into())?;
        set("adminspace/permissions/read", "true".into())?;
        let session = zenoh::open(config).wait().map_err(|e| fail("starting the Zenoh router", e))?;
        Ok(Router { session })
    }

    /// The router's Zenoh id.
    pub fn zid(&self) -> String {
        self.session.zid().to_string()
    }

    /// The endpoints the router listens on, as bound (port 0 resolved; an unspecified address
    /// such as `0.0.0.0` expanded to the host's non-loopback addresses), read from its admin
    /// space (`@/<zid>/router`).
    pub fn locators(&self) -> Result<Vec<String>, RuntimeError> {
        let key = format!("@/{}/router", self.zid());
        let replies = self.session.get(&key).wait().map_err(|e| fail("asking the router's admin space", e))?;
        while let Ok(reply) = replies.recv() {
            let Ok(sample) = reply.result() else { continue };
            let json: serde_json::Value = serde_json::from_slice(&sample.payload().to_bytes())
                .map_err(|e| fail("reading the router's admin space", e))?;
            let locators = json["locators"].as_array().map(|l| l.iter().filter_map(|v| v.as_str()).map(str::to_owned));
            return Ok(locators.map(Iterator::collect).unwrap_or_default());
        }
        Err(fail("asking the router's admin space", format!("no answer on {key}")))
    }

    /// The Zenoh session (for diagnostics, and for tests that publish through the router).
    pub fn session(&self) -> &Session {
        &self.session
    }

    /// Close the router (its links drop; clients reconnect to another router if they have one).
    pub fn close(self) -> Result<(), RuntimeError> {
        self.session.close().wait().map_err(|e| fail("closing the Zenoh router", e))
    }
}

/// `ayllu-zenoh router`'s usage.
pub const USAGE: &str = "usage: ayllu-zenoh router [--listen ENDPOINT]... [--connect ENDPOINT]... [--config FILE] \
                         [--scouting 0|1] [--for SECONDS]\n  e.g. ayllu-zenoh router --listen tcp/0.0.0.0:7447";

/// A `--for SECONDS` value (the router's and the bridge's): a finite, non-negative number of
/// seconds, fractions allowed.
pub(crate) fn seconds(value: &str) -> Option<std::time::Duration> {
    match value.parse::<f64>() {
        Ok(s) if s.is_finite() && s >= 0.0 => Some(std::time::Duration::from_secs_f64(s)),
        _ => None,
    }
}

/// `ayllu-zenoh router ARGS`: start a router, print one JSON line
/// `{"router":ZID,"locators":[...]}` (the bound endpoints: port 0 resolved) and run until killed
/// or `--for` seconds have passed. Returns the exit status (2: usage, 1: the router failed).
pub fn router_main(args: &[String]) -> std::process::ExitCode {
    let usage = |why: &str| {
        eprintln!("ayllu-zenoh router: {why}\n{USAGE}");
        std::process::ExitCode::from(2)
    };
    let mut options = RouterOptions::default();
    let mut run_for = None;
    let mut it = args.iter();
    while let Some(flag) = it.next() {
        if flag == "-h" || flag == "--help" {
            println!("{USAGE}");
            return std::process::ExitCode::SUCCESS;
        }
        let Some(value) = it.next() else { return usage(&format!("{flag} needs a value")) };
        match flag.as_str() {
            "--listen" => options.listen.push(value.clone()),
            "--connect" => options.connect.push(value.clone()),
            "--config" => options.config_file = Some(value.clone()),
            "--scouting" => match value.as_str() {
                "0" | "false" => options.scouting = Some(false),
                "1" | "true" => options.scouting = Some(true),
                _ => return usage(&format!("--scouting takes 0 or 1, got `{value}`")),
            },
            "--for" => match seconds(value) {
                Some(d) => run_for = Some(d),
                None => return usage(&format!("--for takes seconds, got `{value}`")),
            },
            _ => return usage(&format!("unknown option `{flag}`")),
        }
    }
    let router = match Router::open(&options).and_then(|r| r.locators().map(|l| (r, l))) {
        Ok(ok) => ok,
        Err(e) => {
            eprintln!("ayllu-zenoh router: {e}");
            return std::process::ExitCode::from(1);
        }
    };
    let (router, locators) = router;
    println!("{}", serde_json::json!({ "router": router.zid(), "locators": locators }));
    match run_for {
        Some(d) => std::thread::sleep(d),
        // Zenoh's threads do the routing; this one only keeps the process alive until killed.
        None => loop {
            std::thread::park();
        },
    }
    match router.close() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("ayllu-zenoh router: {e}");
            std::process::ExitCode::from(1)
        }
    }
}
