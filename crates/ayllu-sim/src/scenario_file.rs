//! Scenarios and sweeps as data: TOML files that `ayllu sim run` and `ayllu sim sweep` read,
//! and that any program can read through this module (docs/cmommt.md, "Studies as files").
//!
//! A scenario file starts from the simulator's standard scenario for a team and overrides any
//! field of [`Scenario`] (the arena, the world's sensors and targets, the radio's loss, delay,
//! jitter, range and partitions, kills at any instants, the controllers' tunables, seed,
//! duration, frame and tick rates):
//!
//! ```toml
//! controller = "BLE"       # BLE, Random, Local, ForceField, Centralized, Planner, BLE-lean, BLE-seek
//! robots = 3
//! targets = 4              # priorities 4, 3, 2, 1 (or list world.targets yourself)
//! seed = 1
//! duration = 300.0
//! [radio]
//! loss = 0.1
//! [[kills]]
//! at = 150.0
//! robot = 2
//! [base_station_failure]    # the Planner's base station lost (nothing for the others)
//! at = 200.0
//! how = "killed"           # or "partitioned" (optionally `until`)
//! [controllers]
//! eligibility = "lean"     # or "paper"
//! ```
//!
//! A sweep file is a scenario file plus `seeds` (runs per cell, seeds 1..=N), `controllers`
//! (names; `compare` when the file also has a `[controllers]` table of tunables), optional
//! `[[cases]]` (each a `title` and fields laid over the file's: settings that differ in several
//! fields at once) and a `[grid]` table mapping field paths (`radio.loss`, `robots`,
//! `world.arena`) to lists of values; the cells are the cases (or the file alone), each times
//! the grid's cartesian product, in the order written.
//!
//! Promises: every key must be a field of the scenario (a misspelt key is an error naming it,
//! never silently ignored); tables merge into the defaults, arrays and values replace them;
//! every scenario read, and every run of a sweep, is held to the scenario's bounds
//! ([`Scenario::validate`], crate::bounds) as it is read, so a file out of bounds is refused
//! before anything runs; errors name the file's part that is wrong. Nothing here runs a
//! simulation.

use serde_json::{Map, Value as Json};

use crate::bounds;
use crate::controller::Controller;
use crate::numbers;
use crate::scenario::Scenario;

/// `(field path, value)` of each grid axis.
type Labels = Vec<(String, String)>;

/// A cell being made: its labels and its scenario's table.
type Draft = (Labels, Map<String, Json>);

/// One cell of a sweep: the scenario (seed 1) and the grid values that made it.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepCell {
    /// `(field path, value)` for each grid axis, in the grid's order.
    pub values: Vec<(String, String)>,
    /// The scenario of this cell; run it with seeds 1..=`Sweep::seeds`.
    pub scenario: Scenario,
}

/// A sweep read from a file: cells x controllers x seeds.
#[derive(Clone, Debug, PartialEq)]
pub struct Sweep {
    /// Runs per cell and controller (seeds 1..=seeds).
    pub seeds: u64,
    /// The controllers every cell is run with.
    pub controllers: Vec<Controller>,
    /// The grid's cells, in order.
    pub cells: Vec<SweepCell>,
}

impl Sweep {
    /// Every run: (cell index, controller, seed, scenario), in order.
    pub fn runs(&self) -> Vec<(usize, Controller, u64, Scenario)> {
        let mut runs = Vec::new();
        for (i, cell) in self.cells.iter().enumerate() {
            for &c in &self.controllers {
                for seed in 1..=self.seeds {
                    let mut s = cell.scenario.clone();
                    s.controller = c;
                    s.seed = seed;
                    s.controllers.wander_seed = seed;
                    runs.push((i, c, seed, s));
                }
            }
        }
        runs
    }
}

/// Read a scenario file (module docs).
pub fn scenario(text: &str) -> Result<Scenario, String> {
    let table = parse(text)?;
    scenario_from(table)
}

/// Read a sweep file (module docs).
pub fn sweep(text: &str) -> Result<Sweep, String> {
    let mut table = parse(text)?;
    let seeds = match table.remove("seeds") {
        None => 10,
        Some(v) => v.as_u64().filter(|n| (1..=1000).contains(n)).ok_or("`seeds` must be a number from 1 to 1000")?,
    };
    let controllers: Vec<Controller> = match take_controller_list(&mut table) {
        None => Controller::ALL.to_vec(),
        Some(v) => v
            .as_array()
            .ok_or("`controllers` must be a list of names")?
            .iter()
            .map(|c| c.as_str().and_then(Controller::parse).ok_or(format!("unknown controller {c}")))
            .collect::<Result<_, _>>()?,
    };
    if controllers.is_empty() {
        let names: Vec<&str> = Controller::ALL.iter().map(|c| c.name()).collect();
        return Err(format!("controllers: [] names no controller: a sweep runs at least one of {}", names.join(", ")));
    }
    let grid = match table.remove("grid") {
        None => Map::new(),
        Some(Json::Object(g)) => g,
        Some(_) => return Err("`grid` must be a table of field = [values]".into()),
    };
    // What `Sweep::runs` sets for every run would be silently overwritten: refused, saying
    // what sets it instead.
    let wander_seed = table.get("controllers").and_then(|c| c.get("wander_seed")).is_some();
    for (path, given) in [
        ("seed", table.contains_key("seed")),
        ("controller", table.contains_key("controller")),
        ("controllers.wander_seed", wander_seed),
    ] {
        if given {
            return Err(set_by_the_sweep(path, ""));
        }
        if grid.contains_key(path) {
            return Err(set_by_the_sweep(path, "grid."));
        }
    }
    // The cell's scenario is read (and held to the bounds) as the first controller's run; every
    // controller's run is checked below.
    table.insert("controller".into(), Json::String(controllers[0].name().to_owned()));
    let mut cells: Vec<Draft> = match table.remove("cases") {
        None => vec![(Vec::new(), table)],
        Some(cases) => cases_of(&table, cases)?,
    };
    for (path, values) in grid {
        let values =
            values.as_array().filter(|v| !v.is_empty()).ok_or(format!("grid.{path} must be a non-empty list"))?;
        let mut next = Vec::new();
        for (labels, base) in &cells {
            for v in values {
                let mut t = base.clone();
                set_path(&mut t, &path, v.clone())?;
                let mut labels = labels.clone();
                labels.push((path.clone(), v.to_string()));
                next.push((labels, t));
            }
        }
        cells = next;
    }
    let cells: Vec<SweepCell> = cells
        .into_iter()
        .enumerate()
        .map(|(i, (values, t))| {
            // Each run of the cell, as `Sweep::runs` makes it, is held to the bounds (a partition
            // may name the Planner's base station only in the Planner's runs).
            let checked = scenario_from(t).and_then(|scenario| {
                for &c in &controllers {
                    Scenario { controller: c, ..scenario.clone() }.validate().map_err(|e| e.to_string())?;
                }
                Ok(scenario)
            });
            let scenario = checked.map_err(|e| {
                if values.is_empty() {
                    return e;
                }
                let at: Vec<String> = values.iter().map(|(k, v)| format!("{k} = {v}")).collect();
                format!("cell{} ({}): {e}", i + 1, at.join(", "))
            })?;
            Ok(SweepCell { scenario, values })
        })
        .collect::<Result<_, String>>()?;
    Ok(Sweep { seeds, controllers, cells })
}

/// The cells of a sweep's `[[cases]]`: each case is the sweep's scenario with the case's
/// fields laid over it (tables field by field, anything else replaced), labelled by its
/// `title` (default `case N`); the grid, if any, then multiplies them.
fn cases_of(table: &Map<String, Json>, cases: Json) -> Result<Vec<Draft>, String> {
    let cases = cases.as_array().filter(|c| !c.is_empty()).ok_or("`cases` must be a non-empty list of tables")?;
    let mut cells = Vec::with_capacity(cases.len());
    for (i, case) in cases.iter().enumerate() {
        let mut case = case.as_object().cloned().ok_or(format!("cases[{i}] must be a table of fields"))?;
        let title = match case.remove("title") {
            None => format!("case {}", i + 1),
            Some(Json::String(t)) => t,
            Some(other) => return Err(format!("cases[{i}].title must be text, not {other}")),
        };
        let wander_seed = case.get("controllers").and_then(|c| c.get("wander_seed")).is_some();
        for (path, given) in [
            ("seed", case.contains_key("seed")),
            ("controller", case.contains_key("controller")),
            ("controllers.wander_seed", wander_seed),
        ] {
            if given {
                return Err(set_by_the_sweep(path, &format!("cases[{i}].")));
            }
        }
        let mut t = table.clone();
        for (k, v) in case {
            overlay(&mut t, k, v);
        }
        cells.push((vec![(CASE.to_owned(), title)], t));
    }
    Ok(cells)
}

/// The label of a cell's case (`[[cases]]`), whose value is the case's title.
pub const CASE: &str = "case";

/// Lay `value` over `table[key]`: tables field by field, anything else replaced.
fn overlay(table: &mut Map<String, Json>, key: String, value: Json) {
    match (table.get_mut(&key), value) {
        (Some(Json::Object(base)), Json::Object(over)) => {
            for (k, v) in over {
                overlay(base, k, v);
            }
        }
        (_, value) => {
            table.insert(key, value);
        }
    }
}

/// Why a sweep file may not set `path` (`at` is `grid.` when the grid names it).
fn set_by_the_sweep(path: &str, at: &str) -> String {
    let instead = match path {
        "seed" | "controllers.wander_seed" => {
            "every cell runs seeds 1..=`seeds` (each run's wander seed is its seed): set `seeds`, the number of runs a cell"
        }
        _ => "list the controllers to run in `controllers` (or `compare`, beside a [controllers] table)",
    };
    format!("{at}{path} is set by the sweep for each run, so it would be ignored: {instead}")
}

/// In a sweep file `controllers` is the list of controllers to run, unless it is a table (the
/// scenario's controller tunables); a file that sets both names the list `compare` (TOML has
/// one value per key).
fn take_controller_list(table: &mut Map<String, Json>) -> Option<Json> {
    if let Some(list) = table.remove("compare") {
        return Some(list);
    }
    if table.get("controllers").is_some_and(Json::is_array) {
        table.remove("controllers")
    } else {
        None
    }
}

fn parse(text: &str) -> Result<Map<String, Json>, String> {
    let value: toml::Value = toml::from_str(text).map_err(|e| format!("not a valid TOML file: {e}"))?;
    match json(value) {
        Json::Object(m) => Ok(m),
        _ => Err("expected a TOML table".into()),
    }
}

/// A TOML value as the scenario's JSON data: TOML's `nan` and `inf`, which JSON cannot write,
/// become the strings the scenario's numbers read (crate::numbers), so that the bounds, not the
/// parser, refuse them and name their field; dates become their text.
fn json(value: toml::Value) -> Json {
    match value {
        toml::Value::String(s) => Json::String(s),
        toml::Value::Integer(i) => Json::from(i),
        toml::Value::Float(f) if f.is_finite() => Json::from(f),
        toml::Value::Float(f) => Json::String(numbers::non_finite_text(f).to_owned()),
        toml::Value::Boolean(b) => Json::Bool(b),
        toml::Value::Datetime(d) => Json::String(d.to_string()),
        toml::Value::Array(a) => Json::Array(a.into_iter().map(json).collect()),
        toml::Value::Table(t) => Json::Object(t.into_iter().map(|(k, v)| (k, json(v))).collect()),
    }
}

fn scenario_from(mut table: Map<String, Json>) -> Result<Scenario, String> {
    let controller = match table.remove("controller") {
        None => Controller::Ble,
        Some(v) => v.as_str().and_then(Controller::parse).ok_or(format!("unknown controller {v}"))?,
    };
    // The room is sized for the team and the targets' list made before the scenario exists:
    // their bounds are asked first.
    let robots = match table.get("robots") {
        None => 3,
        Some(v) => bounds::robots(v.as_u64(), v).map_err(|e| e.to_string())?,
    };
    let listed = table.get("world").and_then(|w| w.get("targets")).and_then(Json::as_array).map(Vec::len);
    let targets = match table.remove("targets") {
        None => 4,
        Some(v) => {
            let n = bounds::targets("targets", v.as_u64(), &v).map_err(|e| e.to_string())?;
            // The list replaces the targets `targets` made: a count it contradicts would be
            // silently dropped. (An empty list is the bounds' to refuse, by its own name.)
            if let Some(listed) = listed.filter(|&l| l != n && l > 0) {
                return Err(format!(
                    "targets = {n} but world.targets lists {listed}: give one of them, or make them agree"
                ));
            }
            n
        }
    };
    let seed = table.get("seed").and_then(Json::as_u64).unwrap_or(1);
    if let Some(Json::Object(c)) = table.get_mut("controllers") {
        if let Some(e) = c.get("eligibility").and_then(Json::as_str) {
            let policy = match e {
                "paper" => ayllu::stdlib::Eligibility::EveryActivation,
                "lean" => ayllu::stdlib::Eligibility::LEAN,
                other => return Err(format!("controllers.eligibility `{other}`: expected \"paper\" or \"lean\"")),
            };
            c.insert("eligibility".into(), serde_json::to_value(policy).map_err(|e| e.to_string())?);
        }
    }
    let base = Scenario::sized(controller, robots, targets, seed);
    let mut merged = serde_json::to_value(&base).map_err(|e| e.to_string())?;
    // Left out of the standard scenario's form while `None`, but a field a file may set.
    if let Json::Object(m) = &mut merged {
        m.entry("base_station_failure").or_insert(Json::Null);
    }
    merge(&mut merged, Json::Object(table), "")?;
    let scenario: Scenario = serde_json::from_value(merged).map_err(|e| format!("the scenario does not fit: {e}"))?;
    scenario.validate().map_err(|e| e.to_string())?;
    Ok(scenario)
}

/// Merge `over` into `base`: tables field by field (every key must exist in `base`), anything
/// else replaces. `at` is the path so far, for errors.
fn merge(base: &mut Json, over: Json, at: &str) -> Result<(), String> {
    match (base, over) {
        (Json::Object(b), Json::Object(o)) => {
            for (k, v) in o {
                let path = if at.is_empty() { k.clone() } else { format!("{at}.{k}") };
                let slot = b.get_mut(&k).ok_or(format!("unknown field `{path}`"))?;
                merge(slot, v, &path)?;
            }
            Ok(())
        }
        (b, o) => {
            *b = o;
            Ok(())
        }
    }
}

/// Set `path` (`radio.loss`) in `table` to `value`, making tables on the way.
fn set_path(table: &mut Map<String, Json>, path: &str, value: Json) -> Result<(), String> {
    let mut parts = path.split('.').peekable();
    let mut here = table;
    while let Some(p) = parts.next() {
        if parts.peek().is_none() {
            here.insert(p.to_owned(), value);
            return Ok(());
        }
        let next = here.entry(p.to_owned()).or_insert_with(|| Json::Object(Map::new()));
        here = next.as_object_mut().ok_or(format!("grid path `{path}`: `{p}` is not a table"))?;
    }
    Err(format!("empty grid path `{path}`"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scenario_file_overrides_any_field_and_refuses_unknown_ones() {
        let s = scenario(
            r#"
            controller = "local"
            robots = 5
            targets = 6
            seed = 7
            duration = 60.0
            [radio]
            loss = 0.2
            range = 4.0
            [[radio.partitions]]
            start = 10.0
            end = 20.0
            island = [1, 2]
            [[kills]]
            at = 30.0
            robot = 2
            [[kills]]
            at = 30.0
            [world]
            arena = [12.0, 9.0]
            [controllers]
            claim_hz = 2.0
            eligibility = "lean"
            "#,
        )
        .unwrap();
        assert_eq!((s.controller, s.robots, s.seed, s.duration), (Controller::Local, 5, 7, 60.0));
        assert_eq!(s.world.targets.len(), 6);
        assert_eq!((s.radio.loss, s.radio.range, s.radio.partitions.len()), (0.2, Some(4.0), 1));
        assert_eq!(s.kills.len(), 2);
        assert_eq!(s.world.arena, [12.0, 9.0]);
        assert_eq!(s.controllers.eligibility, ayllu::stdlib::Eligibility::LEAN);
        assert_eq!(s.controllers.claim_hz, 2.0);
        // Untouched fields keep the standard scenario's values.
        let standard = Scenario::sized(Controller::Local, 5, 6, 7);
        assert_eq!(
            (s.dt, s.frame_dt, s.world.camera_range),
            (standard.dt, standard.frame_dt, standard.world.camera_range)
        );

        for (text, needle) in [
            ("[radio]\nlos = 0.1", "unknown field `radio.los`"),
            ("controler = \"BLE\"", "unknown field `controler`"),
            ("controller = \"Oracle\"", "unknown controller"),
            ("[radio]\nloss = \"much\"", "does not fit"),
            ("robots = 0", "robots"),
            ("this is not toml", "TOML"),
        ] {
            let err = scenario(text).unwrap_err();
            assert!(err.contains(needle), "{text}: {err}");
        }
    }

    #[test]
    fn a_sweep_is_the_grids_product_times_controllers_times_seeds() {
        let sw = sweep(
            r#"
            seeds = 3
            controllers = ["BLE", "Random"]
            duration = 30.0
            [grid]
            robots = [2, 4]
            "radio.loss" = [0.0, 0.1, 0.3]
            "#,
        )
        .unwrap();
        assert_eq!((sw.seeds, sw.controllers.len(), sw.cells.len()), (3, 2, 6));
        assert_eq!(sw.runs().len(), 6 * 2 * 3);
        let last = &sw.cells[5];
        assert_eq!((last.scenario.robots, last.scenario.radio.loss, last.scenario.duration), (4, 0.3, 30.0));
        assert_eq!(
            last.values,
            vec![("robots".to_owned(), "4".to_owned()), ("radio.loss".to_owned(), "0.3".to_owned())]
        );
        assert!(sweep("[grid]\n\"radio.los\" = [0.1]").unwrap_err().contains("radio.los"));
        // The list and the tunables together: the list is `compare`.
        let both = sweep("compare = [\"Planner\"]\n[controllers]\nplan_hz = 4.0\n").unwrap();
        assert_eq!(both.controllers, [Controller::Planner]);
        assert_eq!(both.cells[0].scenario.controllers.plan_hz, 4.0);
    }

    /// `[[cases]]`: settings that differ in several fields at once, laid over the file's,
    /// each multiplied by the grid; a case may not set what the sweep sets for each run.
    #[test]
    fn cases_are_cells_laid_over_the_file_and_multiplied_by_the_grid() {
        let sw = sweep(
            r#"
            seeds = 1
            compare = ["BLE", "Planner"]
            robots = 4
            [radio]
            delay = 0.01
            [[cases]]
            title = "as is"
            [[cases]]
            title = "lossy, base station lost"
            radio = { loss = 0.2 }
            base_station_failure = { at = 5.0, how = "partitioned", until = 9.0 }
            [[cases]]
            robots = 2
            [grid]
            duration = [10.0, 20.0]
            "#,
        )
        .unwrap();
        assert_eq!(sw.cells.len(), 6);
        let lossy = &sw.cells[2].scenario;
        // The case's table merged into the file's: its loss, the file's delay.
        assert_eq!((lossy.radio.loss, lossy.radio.delay, lossy.robots, lossy.duration), (0.2, 0.01, 4, 10.0));
        let failure = lossy.base_station_failure.as_ref().unwrap();
        assert_eq!((failure.at, failure.until), (5.0, Some(9.0)));
        assert_eq!(sw.cells[0].scenario.base_station_failure, None);
        assert_eq!(sw.cells[5].scenario.robots, 2);
        assert_eq!(sw.cells[2].values[0], (CASE.to_owned(), "lossy, base station lost".to_owned()));
        assert_eq!(sw.cells[4].values[0].1, "case 3");
        let err = sweep(
            "[[cases]]
seed = 3
",
        )
        .unwrap_err();
        assert!(err.contains("cases[0].seed is set by the sweep"), "{err}");
        let err = sweep(
            "[[cases]]
base_station_failure = { at = 5.0, how = \"killed\", until = 6.0 }
",
        )
        .unwrap_err();
        assert!(err.contains("base_station_failure.until"), "{err}");
        let err = sweep(
            "[[cases]]
radio = { los = 0.1 }
",
        )
        .unwrap_err();
        assert!(err.contains("radio.los"), "{err}");
    }

    /// What every run of a sweep sets itself (its seed, its controller, the wander seed that
    /// follows the seed) was silently overwritten when a sweep file set it, at the top or in
    /// the grid: every cell then ran the same runs under different titles.
    #[test]
    fn a_sweep_refuses_the_fields_it_sets_for_each_run() {
        for (text, needle) in [
            ("seed = 5", "seed is set by the sweep"),
            ("controller = \"Local\"", "controller is set by the sweep"),
            ("[controllers]\nwander_seed = 3", "controllers.wander_seed is set by the sweep"),
            ("[grid]\nseed = [5, 6]", "grid.seed is set by the sweep"),
            ("[grid]\ncontroller = [\"Random\", \"Local\"]", "grid.controller is set by the sweep"),
            ("[grid]\n\"controllers.wander_seed\" = [3, 4]", "grid.controllers.wander_seed is set by"),
        ] {
            let err = sweep(text).unwrap_err();
            assert!(err.contains(needle), "{text}: {err}");
            let instead = if needle.contains("controller ") { "`controllers`" } else { "`seeds`" };
            assert!(err.contains(instead), "{text}: {err}");
        }
        // A scenario file (one run) still takes them.
        assert_eq!(scenario("seed = 5\ncontroller = \"Local\"").unwrap().seed, 5);
    }

    /// `targets` and a `world.targets` list of another length contradict each other: the list
    /// replaced the targets the count made, without a word.
    #[test]
    fn a_target_count_the_target_list_contradicts_is_refused() {
        let one = "[world]\ntargets = [{priority = 1.0, speed = 0.1, motion = \"Static\"}]";
        let err = scenario(&format!("targets = 3\n{one}")).unwrap_err();
        assert!(err.contains("targets = 3 but world.targets lists 1"), "{err}");
        assert_eq!(scenario(&format!("targets = 1\n{one}")).unwrap().world.targets.len(), 1);
        assert_eq!(scenario(one).unwrap().world.targets.len(), 1);
    }
}
