//! `ayllu apply PLAN.toml`: structure changes on several nodes, applied by all of them at one
//! instant or by none (docs/cli.md "ayllu apply"; docs/semantics.md R8–R12).
//!
//! Only the arguments and the printing are here: the plan's file format is
//! `ayllu::plan_file`, the protocol `ayllu::transaction`. Exit codes: 0 the team switched;
//! 1 it did not (aborted: which node refused and why; split: which nodes did not answer
//! COMMIT) or a node could not be found; 2 a plan file that does not parse.

use std::path::Path;

use ayllu::transaction::{apply, Outcome, Plan};

use crate::client::Client;
use crate::commands::emit;
use crate::fail::Fail;
use crate::Net;

/// How long to look for each node of the plan (its HELLO) unless `--timeout` says otherwise.
const FIND_TIMEOUT: f64 = 5.0;

/// Run `ayllu apply`.
pub fn apply_command(plan: &Path, net: &Net) -> Result<(), Fail> {
    let plan = Plan::read(plan).map_err(|e| Fail::usage(e.to_string()))?;
    let mut client = Client::open(net, FIND_TIMEOUT)?;
    for part in &plan.parts {
        client.find(part.node)?;
    }
    let report = apply(&mut client.node, &plan)?;
    if net.json {
        emit(&report.to_json().to_string())?;
    } else {
        emit(&report.to_string())?;
    }
    match report.outcome {
        Outcome::Switched => Ok(()),
        Outcome::Aborted => {
            let why: Vec<String> = report.refused().iter().map(|(n, e)| format!("{n} refused: {e}")).collect();
            let why = if why.is_empty() { "a node did not answer PREPARE".to_owned() } else { why.join("; ") };
            Err(Fail::error(format!("no node switched: {why}")))
        }
        Outcome::Split => {
            let unsure: Vec<String> =
                report.nodes.iter().filter(|n| matches!(n.commit, Some(Err(_)))).map(|n| n.node.to_string()).collect();
            Err(Fail::error(format!(
                "the team is split: {} did not answer COMMIT (switched late, or aborted by itself at the end of its \
                 hold); check with `ayllu list` and apply again",
                unsure.join(", ")
            )))
        }
    }
}
