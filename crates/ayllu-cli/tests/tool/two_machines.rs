//! Tutorial 8 (docs/tutorials/08-two-machines.md) as its reader runs it: one program per robot,
//! each on its own "machine" (a network namespace on a bridge the test creates), both given the
//! tutorial's `AYLLU_URL` and nothing else, on the real clock. The Rust, Python and C programs
//! are run against each other (Rust and Python in both roles, C with Python), so each is shown
//! to make a team with the others across machines.
//!
//! The page's recipe for two machines on one computer (`two_namespaces.sh`) runs as printed too,
//! and the output the page quotes has the shape of what robot 1 prints.
//!
//! The Rust program runs as a process of this very test binary (the ignored test
//! `robot_process`, which does nothing unless [`ROBOT`] is set); the Python one with the
//! project's venv (`scripts/python-venv`, which `make test` builds first). Without root or `ip`
//! the test fails, naming what is missing, unless `AYLLU_SKIP=netns` asks to skip it.

use crate::common;

use std::path::PathBuf;
use std::process::Command;
use std::time::Duration;

use common::netns::Netns;

#[path = "../../../../examples/tutorial/08_two_machines/main.rs"]
#[allow(dead_code)] // its `main` is for `cargo run --example`
mod program;

/// The environment variable that makes [`robot_process`] run robot `ID`.
const ROBOT: &str = "AYLLU_TUTORIAL_8_ROBOT";
/// The tutorial's URL, as its page gives it.
const URL: &str = "udp://0.0.0.0:0?discovery=239.255.65.89:7390&ttl=1";
/// Seconds each robot runs.
const SECONDS: &str = "6";

/// Not a test of its own: the Rust robot's `main`, which the tests below start as a process of
/// this binary in each namespace (ignored, so that a plain run does not start it; run alone it
/// fails, saying so, rather than pass having done nothing).
#[test]
#[ignore = "one robot of tutorial 8, run as a process by the tutorial_8 tests"]
fn robot_process() {
    let id = std::env::var(ROBOT).unwrap_or_else(|_| {
        panic!("robot_process is one robot of tutorial 8, started by the tutorial_8 tests with {ROBOT}=ID")
    });
    let id: u32 = id.parse().expect("a robot id");
    let seconds = SECONDS.parse().unwrap();
    if let Err(e) = program::run(id, &ayllu::default_url(), seconds) {
        eprintln!("{e}");
        std::process::exit(1);
    }
}

/// The project's venv python: `$AYLLU_PY_VENV`, else `ayllu-py-venv` in this binary's target
/// directory (`target/debug/deps/tool-*` lives three levels down).
fn venv_python() -> PathBuf {
    let venv = std::env::var_os("AYLLU_PY_VENV").map(PathBuf::from).unwrap_or_else(|| {
        let exe = std::env::current_exe().expect("this test's path");
        exe.ancestors().nth(3).expect("the target directory").join("ayllu-py-venv")
    });
    let python = venv.join("bin/python");
    assert!(python.exists(), "{} is missing: run scripts/python-venv first (make test does)", python.display());
    python
}

/// Robot `id` in namespace `i`, in `language` (`rust`, `python` or `c`: the C program as
/// `make -C crates/ayllu-c` builds it, which `make test` does before the tests run).
fn robot(net: &Netns, i: usize, id: u32, language: &str) -> Command {
    let mut cmd = match language {
        "rust" => {
            let mut cmd = net.command(i, std::env::current_exe().unwrap().to_str().unwrap());
            cmd.args(["two_machines::robot_process", "--exact", "--ignored", "--nocapture", "--test-threads=1", "-q"]);
            cmd.env(ROBOT, id.to_string());
            cmd
        }
        "c" => {
            let program = concat!(env!("CARGO_MANIFEST_DIR"), "/../ayllu-c/build/tutorial_08_two_machines");
            assert!(
                std::path::Path::new(program).exists(),
                "{program} is missing: make -C crates/ayllu-c build/tutorial_08_two_machines (make test builds it)"
            );
            let mut cmd = net.command(i, program);
            cmd.args([&id.to_string(), "--for", SECONDS]);
            cmd
        }
        _ => {
            let mut cmd = net.command(i, venv_python().to_str().unwrap());
            let program = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/tutorial/08_two_machines/main.py");
            cmd.args([program, &id.to_string(), "--for", SECONDS]);
            cmd
        }
    };
    cmd.env("AYLLU_URL", URL);
    cmd
}

/// `text` with every run of digits as `#`, a duration's unit as `s` (`42ms`, `3us`, `1.2s` are
/// one shape) and spaces collapsed: the shape of a line whose times, addresses and ages differ
/// from run to run.
fn shape(text: &str) -> Vec<String> {
    text.lines()
        .map(|l| {
            let mut out = String::new();
            for c in l.split_whitespace().collect::<Vec<_>>().join(" ").chars() {
                if !(c.is_ascii_digit() && out.ends_with('#')) {
                    out.push(if c.is_ascii_digit() { '#' } else { c });
                }
            }
            out.replace("#ms", "#s").replace("#us", "#s").replace("#ns", "#s")
        })
        .collect()
}

/// The output the page quotes (its first ```text block, robot 1 in Rust), but for "...", has
/// the shape of what robot 1 printed here.
fn the_page_quotes(printed: &str) {
    let page = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/tutorials/08-two-machines.md"))
        .expect("the tutorial's page");
    let start = page.find("\n```text\n").expect("the page quotes output") + "\n```text\n".len();
    let quoted = &page[start..start + page[start..].find("```").unwrap()];
    let printed = shape(printed);
    for line in shape(quoted).into_iter().filter(|l| l != "...") {
        assert!(printed.contains(&line), "the page quotes `{line}`, which robot 1 did not print: {printed:#?}");
    }
}

/// Robots 1 and 2 in `languages`, on two machines of a new subnet; checks what each prints.
fn team(tag: &str, subnet: u8, languages: [&'static str; 2]) {
    let net = match Netns::create(tag, subnet, 2) {
        Ok(net) => net,
        Err(reason) => return common::unavailable("netns", &reason),
    };
    let runs: Vec<common::Run> = std::thread::scope(|s| {
        let net = &net;
        let handles: Vec<_> = (0..2)
            .map(|i| s.spawn(move || common::run(robot(net, i, i as u32 + 1, languages[i]), Duration::from_secs(40))))
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    for (i, run) in runs.iter().enumerate() {
        let (id, other) = (i as u32 + 1, program::partner(i as u32 + 1));
        let who = format!("robot {id} ({})", languages[i]);
        assert_eq!(run.code, Some(0), "{who} did not end well: {run:?}");
        // Its motor held the other robot's reading, supplied along the other robot's connection.
        let reading = format!("MOTOR.Speed = {:.1} from n{other}/", program::range_of(other));
        assert!(run.stdout.contains(&reading), "{who} printed no `{reading}`: {run:?}");
        if languages[i] != "c" {
            // The C program prints the values only (its why is JSON, ayWhy).
            assert!(run.stdout.contains(&format!("n{id}:MOTOR.Speed (normal float)")), "{who} printed why: {run:?}");
            assert!(run.stdout.contains(&format!("supplier  n{other}/")), "{who}'s why names the other robot: {run:?}");
        }
        if languages[i] == "rust" {
            assert!(run.stdout.contains(&format!("heard robot {other} at {}:", net.addr(1 - i))), "{who}: {run:?}");
            if id == 1 {
                the_page_quotes(&run.stdout);
            }
        }
        eprintln!("--- {who}\n{}", run.stdout);
    }
}

#[test]
fn tutorial_8_a_rust_robot_and_a_python_robot_on_two_machines() {
    team("ta", 87, ["rust", "python"]);
}

#[test]
fn tutorial_8_a_python_robot_and_a_rust_robot_on_two_machines() {
    team("tb", 88, ["python", "rust"]);
}

#[test]
fn tutorial_8_a_c_robot_and_a_python_robot_on_two_machines() {
    team("tc", 90, ["c", "python"]);
}

#[test]
fn tutorial_8_the_pages_two_namespace_recipe_runs() {
    // The page's recipe for two machines on one computer, as printed (its own namespaces and
    // bridge, named after this process so that two suites never share them), with the Python
    // robots.
    let root = std::process::Command::new("id").arg("-u").output().map(|o| o.stdout == b"0\n").unwrap_or(false);
    let ip = std::process::Command::new("ip").arg("-V").output().is_ok();
    if !root || !ip {
        return common::unavailable("netns", if root { "no `ip` command" } else { "not root" });
    }
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/tutorial/08_two_machines");
    let mut cmd = Command::new("sh");
    cmd.arg(format!("{dir}/two_namespaces.sh"))
        .arg(venv_python())
        .arg(format!("{dir}/main.py"))
        .args(["--for", SECONDS])
        .env("PREFIX", format!("t8{}", std::process::id() % 100_000));
    let run = common::run(cmd, Duration::from_secs(60));
    assert_eq!(run.code, Some(0), "the recipe did not end well: {run:?}");
    for (id, other) in [(1, 2), (2, 1)] {
        let reading = format!("MOTOR.Speed = {:.1} from n{other}/c1", program::range_of(other));
        assert!(run.stdout.contains(&reading), "robot {id} printed no `{reading}`: {run:?}");
    }
}
