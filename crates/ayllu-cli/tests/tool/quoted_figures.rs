//! What the README, the book and the Makefile quote about the tool stays true: the counts they
//! give (the study's runs, its baselines), the commands they name and the time they promise are
//! checked against the tool itself (its `--help`, and the study's plan in `ayllu_sim::study`),
//! so that they cannot go stale again when the tool changes. They did once: "1400 runs" and
//! "four baselines" outlived the Planner by weeks.
//!
//! What is checked, and where:
//! * **The study's runs**: in every paragraph of README.md, Makefile and docs/ that speaks of
//!   the study `make demo` and `ayllu sim cmommt` run, "N runs" is the full study's count or
//!   `--quick`'s; the tool's own `sim cmommt --help` too, with its cells.
//! * **Baselines**: "N baselines" anywhere is the number of controllers other than BLE.
//! * **Commands**: every `ayllu COMMAND` (and `ayllu sim SUBCOMMAND`) written anywhere in
//!   README.md, docs/, the Makefile and the examples is a command of `ayllu --help`, and
//!   docs/cli.md has a section for every command the tool has.
//! * **The study's time**: wherever the front door (README.md, the Makefile, docs/index.md, the
//!   tutorials, docs/ros2-users.md) quotes the full study's duration, it is the range
//!   `sim cmommt --help` gives.
//! * **Paths**: every repository path written in backticks exists.
//! * **The tutorials**: every page under docs/tutorials/ is in the book's navigation and in the
//!   front page's table.

use std::path::{Path, PathBuf};

use ayllu_sim::controller::Controller;
use ayllu_sim::study::{Plan, StudyConfig};

use crate::common::{self, BIN};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The front door: where a newcomer reads what the tool promises (the README, the Makefile's
/// messages, the book's front page, the tutorials, the page for ROS 2 users). Measured figures
/// elsewhere in the book (docs/cmommt.md's "15-35 s when idle") are measurements, not promises.
fn front_door(file: &str) -> bool {
    ["README.md", "Makefile", "docs/index.md", "docs/ros2-users.md"].contains(&file)
        || file.starts_with("docs/tutorials/")
}

/// README.md, the Makefile and every page of the book (docs/, recursively), with their paths.
fn quoting_files() -> Vec<(String, String)> {
    let mut files = vec!["README.md".to_owned(), "Makefile".to_owned()];
    let mut dirs = vec![root().join("docs")];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(&dir).unwrap().map(Result::unwrap) {
            let path = entry.path();
            if path.is_dir() {
                dirs.push(path);
            } else if path.extension().is_some_and(|e| e == "md") {
                files.push(path.strip_prefix(root()).unwrap().to_string_lossy().into_owned());
            }
        }
    }
    files.sort();
    files.into_iter().map(|f| (read(&root().join(&f)), f)).map(|(text, f)| (f, text)).collect()
}

/// The tool's output for `args`.
fn tool(args: &[&str]) -> String {
    let mut cmd = std::process::Command::new(BIN);
    cmd.args(args);
    common::run(cmd, std::time::Duration::from_secs(20)).ok().stdout
}

/// The commands a `--help` lists (its "Commands:" section, without `help`).
fn commands(help: &str) -> Vec<String> {
    let section = &help[help.find("Commands:\n").expect("a Commands: section") + "Commands:\n".len()..];
    section
        .lines()
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next())
        .filter(|c| *c != "help")
        .map(str::to_owned)
        .collect()
}

/// A number as the docs write it: digits (with thousands commas) or a word up to twenty.
fn number(token: &str) -> Option<usize> {
    const WORDS: [&str; 21] = [
        "zero",
        "one",
        "two",
        "three",
        "four",
        "five",
        "six",
        "seven",
        "eight",
        "nine",
        "ten",
        "eleven",
        "twelve",
        "thirteen",
        "fourteen",
        "fifteen",
        "sixteen",
        "seventeen",
        "eighteen",
        "nineteen",
        "twenty",
    ];
    let t = token.trim_matches(|c: char| !c.is_ascii_alphanumeric()).to_ascii_lowercase();
    if let Some(n) = WORDS.iter().position(|w| *w == t) {
        return Some(n);
    }
    let digits = t.replace(',', "");
    (!digits.is_empty() && digits.chars().all(|c| c.is_ascii_digit())).then(|| digits.parse().unwrap())
}

/// Paragraphs (blank-line separated), whitespace collapsed.
fn paragraphs(text: &str) -> Vec<String> {
    text.split("\n\n").map(|p| p.split_whitespace().collect::<Vec<_>>().join(" ")).collect()
}

/// The numbers written before `noun` in `paragraph` ("1,680 runs", "1680 simulated runs",
/// "five baselines").
fn counts_of(paragraph: &str, noun: &str) -> Vec<usize> {
    let words: Vec<&str> = paragraph.split(' ').collect();
    (1..words.len())
        .filter(|&i| words[i].trim_matches(|c: char| !c.is_ascii_alphanumeric()) == noun)
        .filter_map(|i| {
            let at = if words[i - 1] == "simulated" && i >= 2 { i - 2 } else { i - 1 };
            // "1 680 runs": a group of three digits after a group of one to three is one number.
            let group = |w: &str, len: std::ops::RangeInclusive<usize>| {
                len.contains(&w.len()) && w.chars().all(|c| c.is_ascii_digit())
            };
            if at >= 1 && group(words[at], 3..=3) && group(words[at - 1].trim_start_matches('('), 1..=3) {
                return number(&format!("{}{}", words[at - 1].trim_start_matches('('), words[at]));
            }
            number(words[at])
        })
        .collect()
}

/// Whether a paragraph speaks of the study `make demo` and `ayllu sim cmommt` run.
fn about_the_study(paragraph: &str) -> bool {
    ["make demo", "sim cmommt", "full study", "the paper's study"].iter().any(|k| paragraph.contains(k))
}

#[test]
fn the_study_runs_quoted_are_the_plans() {
    let full = Plan::new(&StudyConfig::default());
    let quick = Plan::new(&StudyConfig::quick()).runs();
    let help = tool(&["sim", "cmommt", "--help"]);
    // The tool's own help gives the full study's runs and its cells.
    let cells = format!(
        "The full study is {} runs (paper {} cells, sweep {}, robustness {}; x {} seeds",
        full.runs(),
        full.paper.len(),
        full.sweep.len(),
        full.robustness.len(),
        StudyConfig::default().seeds
    );
    assert!(help.contains(&cells), "`ayllu sim cmommt --help` must say {cells:?}:\n{help}");
    assert!(help.contains(&format!("--quick ({quick} runs)")), "the help gives --quick's runs ({quick}):\n{help}");
    let mut wrong = Vec::new();
    for (file, text) in quoting_files() {
        for p in paragraphs(&text).into_iter().filter(|p| about_the_study(p)) {
            for n in counts_of(&p, "runs").into_iter().filter(|&n| n != full.runs() && n != quick) {
                wrong.push(format!("{file}: {n} runs (the full study is {}, --quick {quick}): {p}", full.runs()));
            }
        }
    }
    assert!(wrong.is_empty(), "stale counts of the study's runs:\n{}", wrong.join("\n\n"));
}

#[test]
fn the_baselines_quoted_are_the_controllers_beside_ble() {
    let baselines = Controller::ALL.len() - 1;
    assert!(Controller::ALL.contains(&Controller::Ble));
    let mut wrong = Vec::new();
    for (file, text) in quoting_files() {
        for p in paragraphs(&text) {
            for n in counts_of(&p, "baselines").into_iter().filter(|&n| n != baselines) {
                wrong.push(format!("{file}: {n} baselines (there are {baselines}): {p}"));
            }
        }
    }
    assert!(wrong.is_empty(), "stale counts of baselines:\n{}", wrong.join("\n\n"));
}

#[test]
fn the_study_time_quoted_is_the_helps() {
    // "about 30 CPU-seconds in a release build, so 15-40 s on 2 cores": the range before " on 2 cores".
    let help = tool(&["sim", "cmommt", "--help"]);
    let help_flat = help.split_whitespace().collect::<Vec<_>>().join(" ");
    let at = help_flat.find(" s on 2 cores").expect("the help gives the study's time on 2 cores");
    let range = help_flat[..at].rsplit(' ').next().unwrap().to_owned();
    assert!(range.contains('-'), "a range: {range}");
    let mut wrong = Vec::new();
    for (file, text) in quoting_files().into_iter().filter(|(f, _)| front_door(f)) {
        for p in paragraphs(&text).into_iter().filter(|p| about_the_study(p)) {
            let words: Vec<&str> = p.split(' ').collect();
            for w in words.windows(2) {
                let quoted = w[0].trim_start_matches(['(', '~']);
                let is_range = quoted.split('-').count() == 2 && quoted.split('-').all(|n| number(n).is_some());
                if is_range && w[1].trim_end_matches([',', ';', ')', '.']) == "s" && quoted != range {
                    wrong.push(format!("{file}: {quoted} s (the help says {range} s): {p}"));
                }
            }
        }
    }
    assert!(wrong.is_empty(), "stale times of the study:\n{}", wrong.join("\n\n"));
}

#[test]
fn every_command_named_is_the_tools_and_every_command_is_in_cli_md() {
    let top = commands(&tool(&["--help"]));
    let sim = commands(&tool(&["sim", "--help"]));
    assert!(top.len() >= 16 && top.contains(&"sim".to_owned()), "{top:?}");
    let mut files = quoting_files();
    for dir in ["examples/tutorial", "examples/sim", "examples/ros2", "scripts"] {
        let mut stack = vec![root().join(dir)];
        while let Some(d) = stack.pop() {
            for path in std::fs::read_dir(&d).unwrap().map(|e| e.unwrap().path()) {
                if path.is_dir() {
                    stack.push(path);
                } else if let Ok(text) = std::fs::read_to_string(&path) {
                    files.push((path.strip_prefix(root()).unwrap().to_string_lossy().into_owned(), text));
                }
            }
        }
    }
    let mut unknown = Vec::new();
    for (file, text) in &files {
        // `ayllu X` where a command starts: right after a backtick or a binary's directory
        // (`target/release/ayllu why`), or first on a line of a code block (after a prompt or
        // `sudo`). Prose ("this ayllu was built"), paths (`python/ayllu tests`) and other
        // programs' names (`peer ayllu send`) are not commands.
        let mut fenced = false;
        let fences: Vec<bool> = text
            .lines()
            .map(|l| {
                let fence = l.trim_start().starts_with("```");
                fenced ^= fence;
                fenced && !fence
            })
            .collect();
        for (at, _) in text.match_indices("ayllu ") {
            let line_start = text[..at].rfind('\n').map_or(0, |i| i + 1);
            let line = &text[line_start..text[at..].find('\n').map_or(text.len(), |i| at + i)];
            let in_block = fences[text[..line_start].matches('\n').count()];
            let lead = text[line_start..at].trim_start().trim_start_matches("$ ").trim_start_matches("sudo ");
            let after_dir = ["release/", "debug/", "bin/"].iter().any(|d| text[..at].ends_with(d));
            let starts = text[..at].ends_with('`') || after_dir || (in_block && lead.is_empty());
            if !starts {
                continue;
            }
            let rest: Vec<&str> = text[at + "ayllu ".len()..].split_whitespace().take(2).collect();
            let Some(word) = rest.first().map(|w| w.trim_end_matches(['`', ',', '.', ')', ':', ';', '"', '\''])) else {
                continue;
            };
            // Options (`ayllu --help`), placeholders (`ayllu COMMAND`) and prose ("ayllu node"
            // in a sentence is caught above; "ayllu is", "ayllu's" are not commands).
            if word.starts_with('-') || word.is_empty() || word.chars().all(|c| c.is_ascii_uppercase() || c == '_') {
                continue;
            }
            if !word.chars().all(|c| c.is_ascii_lowercase() || c == '-') {
                continue;
            }
            if !top.iter().any(|c| c == word) {
                unknown.push(format!("{file}: `ayllu {word}` ({})", line.trim()));
            } else if word == "sim" {
                let sub = rest.get(1).map(|w| w.trim_end_matches(['`', ',', '.', ')', ':', ';'])).unwrap_or("");
                let is_sub = sub.chars().all(|c| c.is_ascii_lowercase()) && !sub.is_empty();
                if is_sub && !sim.iter().any(|c| c == sub) {
                    unknown.push(format!("{file}: `ayllu sim {sub}` ({})", line.trim()));
                }
            }
        }
    }
    assert!(
        unknown.is_empty(),
        "commands the tool does not have (ayllu --help: {top:?}; sim: {sim:?}):\n{}",
        unknown.join("\n")
    );

    // A section is a heading that names the command (`sim run` and `sim sweep` share one).
    let cli = read(&root().join("docs/cli.md"));
    let headings: Vec<&str> = cli.lines().filter(|l| l.starts_with("## ")).collect();
    let named = |command: &str| headings.iter().any(|h| h.contains(&format!("`ayllu {command}")));
    let missing: Vec<String> = (top.iter().filter(|c| *c != "sim").cloned())
        .chain(sim.iter().map(|s| format!("sim {s}")))
        .filter(|c| !named(c))
        .map(|c| format!("ayllu {c}"))
        .collect();
    assert!(missing.is_empty(), "docs/cli.md has no section for: {missing:?}");
}

#[test]
fn every_tutorial_is_in_the_navigation_and_on_the_front_page() {
    let nav = read(&root().join("mkdocs.yml"));
    let index = read(&root().join("docs/index.md"));
    let mut pages: Vec<String> = std::fs::read_dir(root().join("docs/tutorials"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|f| f.ends_with(".md"))
        .collect();
    pages.sort();
    assert!(pages.len() >= 8, "{pages:?}");
    for page in &pages {
        assert!(nav.contains(&format!("tutorials/{page}")), "mkdocs.yml's nav lacks tutorials/{page}");
        assert!(index.contains(&format!("(tutorials/{page})")), "docs/index.md's table lacks tutorials/{page}");
    }
}

#[test]
fn every_path_named_exists() {
    // A file or folder of the repository written in backticks (`crates/ayllu-c/benches/c/bench.c`)
    // exists; placeholders (`crates/NAME/src`, `tutorial_NN_NAME.out`) and globs are not paths.
    const TOP: [&str; 8] = ["crates/", "examples/", "lite/", "spec/", "scripts/", "fuzz/", "docs/", "benches/"];
    let mut missing = Vec::new();
    for (file, text) in quoting_files() {
        for quoted in text.split('`').skip(1).step_by(2) {
            let path = quoted.split_whitespace().next().unwrap_or("").trim_end_matches([':', ',', ')']);
            let placeholder =
                path.chars().any(|c| c.is_ascii_uppercase() || c == '*' || c == '{' || c == '$' || c == '<');
            // What a build makes (`crates/ayllu-c/build/...`) is not in a fresh clone.
            let built = path.contains("/build/");
            if TOP.iter().any(|t| path.starts_with(t)) && !placeholder && !built && !root().join(path).exists() {
                missing.push(format!("{file}: `{path}`"));
            }
        }
    }
    missing.sort();
    missing.dedup();
    assert!(missing.is_empty(), "paths that do not exist:\n{}", missing.join("\n"));
}
