//! `ayllu` — the command-line tool for a running Ayllu team (docs/cli.md). Everything is in
//! the `ayllu_cli` library, so that its argument parsing can be fuzzed and tested; this file
//! only runs it.

fn main() -> std::process::ExitCode {
    ayllu_cli::cli_main()
}
