//! `ayllu-zenoh` — the `ayllu` tool (docs/cli.md) with the `zenoh://` transport registered, so
//! its commands that talk to a team through `Client::open` (`list`, `why`, `echo`, `write`, ...)
//! accept `--udp zenoh://...` (docs/zenoh.md says which commands do not yet).

fn main() -> std::process::ExitCode {
    ayllu_zenoh::register();
    ayllu_cli::cli_main()
}
