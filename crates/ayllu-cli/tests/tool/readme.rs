//! The README's team example runs as printed: its shell block (three `ayllu node` robots with
//! no addresses, then `list`, `why` and `write` with no flags) is taken from README.md and run
//! by bash inside a network namespace (one "machine" with zero-configuration discovery), with
//! `target/release/ayllu` replaced by the binary under test. Without root or `ip` it fails,
//! naming what is missing, unless `AYLLU_SKIP=netns` asks to skip it.

use crate::common;

use std::time::Duration;

use common::netns::Netns;
use common::BIN;

/// The README's shell block that starts the team.
fn team_block() -> String {
    let readme = include_str!("../../../../README.md");
    let start = readme.find("```sh\ncargo build --release -p ayllu-cli\n").expect("the team example in README.md");
    let body = &readme[start + "```sh\n".len()..];
    body[..body.find("```").expect("end of the block")].to_owned()
}

#[test]
fn the_readme_team_example_runs_as_printed() {
    let net = match Netns::create("rm", 82, 1) {
        Ok(net) => net,
        Err(reason) => return common::unavailable("netns", &reason),
    };
    let script = team_block()
        .lines()
        .filter(|l| !l.starts_with("cargo build")) // the binary under test is built already
        .map(|l| l.replace("target/release/ayllu", BIN))
        .collect::<Vec<_>>()
        .join("\n");
    // The robots run for 30 s: end them when the example is done.
    let script = format!("set -e\n{script}\nkill $(jobs -p) 2>/dev/null || true\n");
    let mut cmd = net.command(0, "bash");
    cmd.args(["-c", &script]).env_remove("AYLLU_URL");
    let run = common::run(cmd, Duration::from_secs(60));
    assert_eq!(run.code, Some(0), "{run:?}");
    for n in ["n1", "n2", "n3"] {
        assert!(run.stdout.contains(&format!("\n{n} ")), "`ayllu list` shows {n}: {}", run.stdout);
    }
    assert!(run.stdout.contains("n2:OBS1.Rotate (normal float)"), "`ayllu why` answers: {}", run.stdout);
    assert!(run.stdout.contains("wrote 0 to n2:OBS1.Rotate along inhibit"), "`ayllu write`: {}", run.stdout);
    eprintln!("{}", run.stdout);
}
