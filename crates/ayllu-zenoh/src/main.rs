//! `ayllu-zenoh` — the `ayllu` tool (docs/cli.md) with the `zenoh://` transport registered, so
//! every command that joins a team (`list`, `why`, `echo`, `write`, `node`, `sim serve`,
//! `sim robot`, ...) accepts `--udp zenoh://...` (docs/zenoh.md), plus `router`
//! (a Zenoh router: [`ayllu_zenoh::router`]) and `bridge` (a mixed `udp://`/`zenoh://` team:
//! [`ayllu_zenoh::bridge`]).

fn main() -> std::process::ExitCode {
    // `router` is this tool's own command (a Zenoh router, no zenohd needed); the rest is the
    // `ayllu` tool's.
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("router") {
        return ayllu_zenoh::router::router_main(&args[1..]);
    }
    if args.first().map(String::as_str) == Some("bridge") {
        return ayllu_zenoh::bridge::bridge_main(&args[1..]);
    }
    ayllu_zenoh::register();
    ayllu_cli::cli_main()
}
