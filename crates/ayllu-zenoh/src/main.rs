//! `ayllu-zenoh` — the `ayllu` tool (docs/cli.md) with the `zenoh://` transport registered, so
//! its commands that talk to a team through `Client::open` (`list`, `why`, `echo`, `write`, ...)
//! accept `--udp zenoh://...` (docs/zenoh.md says which commands do not yet), plus `router`
//! (a Zenoh router: [`ayllu_zenoh::router`]).

fn main() -> std::process::ExitCode {
    // `router` is this tool's own command (a Zenoh router, no zenohd needed); the rest is the
    // `ayllu` tool's.
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("router") {
        return ayllu_zenoh::router::router_main(&args[1..]);
    }
    ayllu_zenoh::register();
    ayllu_cli::cli_main()
}
