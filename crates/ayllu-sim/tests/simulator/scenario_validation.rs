//! A scenario's bounds (`ayllu_sim::bounds`, docs/cmommt.md "What a scenario may hold"): every
//! field out of bounds — NaN, infinite, negative, zero where it must not be, huge — is refused
//! by `Scenario::validate` with an error naming the field, the value and what it accepts, and
//! `Sim::new`, `run` and the file reader refuse it the same way, before anything is built; a
//! scenario built from arbitrary numbers is either refused or runs without a panic; and what
//! ran before (the lab's defaults, the examples' files, zeros that mean "none") still runs.

use ayllu_sim::bounds::InvalidScenario;
use ayllu_sim::controller::{Controller, PLANNER_NODE};
use ayllu_sim::radio::Partition;
use ayllu_sim::scenario::{run, Kill, Scenario, Sim, SimError};
use ayllu_sim::scenario_file;
use proptest::prelude::*;

const NAN: f64 = f64::NAN;
const INF: f64 = f64::INFINITY;

fn base() -> Scenario {
    Scenario::paper(Controller::Ble, 1).duration(10.0)
}

/// `change` applied to the paper's scenario must be refused naming `field`, whose message
/// shows `value`; `Sim::new` and `run` refuse it with the same error, without building.
fn refused(case: &str, field: &str, value: &str, change: impl Fn(&mut Scenario)) -> InvalidScenario {
    let mut s = base();
    change(&mut s);
    let e = s.validate().err().unwrap_or_else(|| panic!("{case}: accepted"));
    let text = e.to_string();
    assert_eq!(e.field, field, "{case}: {text}");
    assert!(text.starts_with(&format!("{field}: {value} is not a usable ")), "{case}: {text}");
    assert!(!e.accepts.is_empty(), "{case}: says what the field accepts");
    match Sim::new(&s) {
        Err(SimError::Scenario(same)) => assert_eq!(same, e, "{case}"),
        Err(other) => panic!("{case}: {other}"),
        Ok(_) => panic!("{case}: built"),
    }
    assert_eq!(run(&s).unwrap_err(), SimError::Scenario(e.clone()), "{case}");
    e
}

#[test]
fn world_fields_out_of_bounds_are_named() {
    let arena = |a: [f64; 2]| move |s: &mut Scenario| s.world.arena = a;
    let e = refused("zero arena", "world.arena", "[0, 0]", arena([0.0, 0.0]));
    assert_eq!(e.to_string(), "world.arena: [0, 0] is not a usable arena: each side must be finite and in (0, 1e6] m");
    refused("negative side", "world.arena", "[-5, 10]", arena([-5.0, 10.0]));
    refused("huge arena", "world.arena", "[1e300, 1e300]", arena([1e300, 1e300]));
    refused("1e10 arena", "world.arena", "[1e10, 1e10]", arena([1e10, 1e10]));
    refused("1e7 arena (44 TB grid)", "world.arena", "[1e7, 1e7]", arena([1e7, 1e7]));
    refused("NaN side", "world.arena", "[NaN, 8]", arena([NAN, 8.0]));
    refused("infinite side", "world.arena", "[8, inf]", arena([8.0, INF]));
    let grid = refused("grid too large", "world.arena", "[100000, 100000]", arena([1e5, 1e5]));
    assert!(grid.accepts.contains("cells"), "{grid}");

    refused("negative speed", "world.max_speed", "-1", |s| s.world.max_speed = -1.0);
    refused("NaN speed", "world.max_speed", "NaN", |s| s.world.max_speed = NAN);
    refused("huge speed", "world.max_speed", "1e300", |s| s.world.max_speed = 1e300);
    refused("NaN turn", "world.max_turn", "NaN", |s| s.world.max_turn = NAN);
    let big = refused("robot wider than the arena", "world.robot_radius", "100", |s| s.world.robot_radius = 100.0);
    assert!(big.accepts.contains("fit the arena"), "{big}");
    refused("negative radius", "world.robot_radius", "-1", |s| s.world.robot_radius = -1.0);
    refused("target wider than the arena", "world.target_radius", "5", |s| s.world.target_radius = 5.0);
    refused("NaN target height", "world.target_height", "NaN", |s| s.world.target_height = NAN);
    refused("negative focal", "world.focal", "-200", |s| s.world.focal = -200.0);
    refused("negative field of view", "world.camera_fov", "-1", |s| s.world.camera_fov = -1.0);
    refused("field of view over a turn", "world.camera_fov", "7", |s| s.world.camera_fov = 7.0);
    refused("infinite camera range", "world.camera_range", "inf", |s| s.world.camera_range = INF);
    refused("negative observe range", "world.observe_range", "-2", |s| s.world.observe_range = -2.0);
    refused("1e8 sonar beams", "world.sonar_beams", "100000000", |s| s.world.sonar_beams = 100_000_000);
    refused("negative sonar range", "world.sonar_range", "-3", |s| s.world.sonar_range = -3.0);
    refused("no grid cell", "world.sonar_range", "0", |s| {
        s.world.sonar_range = 0.0;
        s.world.robot_radius = 0.0;
    });
    refused("NaN bearing noise", "world.bearing_noise", "NaN", |s| s.world.bearing_noise = NAN);
    refused("negative height noise", "world.height_noise", "-0.1", |s| s.world.height_noise = -0.1);
    refused("negative sonar noise", "world.sonar_noise", "-0.1", |s| s.world.sonar_noise = -0.1);
    refused("miss rate 2", "world.miss_rate", "2", |s| s.world.miss_rate = 2.0);
    refused("NaN miss rate", "world.miss_rate", "NaN", |s| s.world.miss_rate = NAN);
    refused("no targets", "world.targets", "0 targets", |s| s.world.targets.clear());
    refused("negative priority", "world.targets[2].priority", "-1", |s| s.world.targets[2].priority = -1.0);
    refused("NaN priority", "world.targets[0].priority", "NaN", |s| s.world.targets[0].priority = NAN);
    refused("negative target speed", "world.targets[1].speed", "-0.1", |s| s.world.targets[1].speed = -0.1);
}

#[test]
fn the_team_and_the_run_length_are_bounded() {
    refused("no robots", "robots", "0", |s| s.robots = 0);
    refused("too many robots", "robots", "10001", |s| s.robots = 10_001);
    refused("negative duration", "duration", "-5", |s| s.duration = -5.0);
    refused("zero duration", "duration", "0", |s| s.duration = 0.0);
    refused("NaN duration", "duration", "NaN", |s| s.duration = NAN);
    refused("infinite duration", "duration", "inf", |s| s.duration = INF);
    refused("1e300 s", "duration", "1e300", |s| s.duration = 1e300);
    // Within the tool's 1e9 s, but 5e7 frames of coverage, or 2e10 ticks: the limit is named.
    let frames = refused("1e7 s of frames", "duration", "1e7", |s| s.duration = 1e7);
    assert!(frames.accepts.contains("frames"), "{frames}");
    let ticks = refused("1e9 s of ticks", "duration", "1e9", |s| {
        s.duration = 1e9;
        s.frame_dt = 1e6;
    });
    assert!(ticks.accepts.contains("ticks"), "{ticks}");
    refused("zero tick", "dt", "0", |s| s.dt = 0.0);
    refused("NaN tick", "dt", "NaN", |s| s.dt = NAN);
    refused("2 s tick", "dt", "2", |s| s.dt = 2.0);
    refused("negative frame period", "frame_dt", "-1", |s| s.frame_dt = -1.0);
    refused("NaN frame period", "frame_dt", "NaN", |s| s.frame_dt = NAN);
    let record = refused("recording too large", "record", "true", |s| {
        s.duration = 1e6;
        s.record = true;
    });
    assert!(record.accepts.contains("poses"), "{record}");
}

#[test]
fn radio_fields_out_of_bounds_are_named() {
    refused("loss 2", "radio.loss", "2", |s| s.radio.loss = 2.0);
    refused("negative loss", "radio.loss", "-0.5", |s| s.radio.loss = -0.5);
    refused("NaN loss", "radio.loss", "NaN", |s| s.radio.loss = NAN);
    refused("negative range", "radio.range", "-1", |s| s.radio.range = Some(-1.0));
    refused("NaN range", "radio.range", "NaN", |s| s.radio.range = Some(NAN));
    refused("infinite range", "radio.range", "inf", |s| s.radio.range = Some(INF));
    refused("negative delay", "radio.delay", "-1", |s| s.radio.delay = -1.0);
    refused("NaN delay", "radio.delay", "NaN", |s| s.radio.delay = NAN);
    refused("a minute's delay", "radio.delay", "60", |s| s.radio.delay = 60.0);
    refused("negative jitter", "radio.jitter", "-1", |s| s.radio.jitter = -1.0);
    let flight = refused("a big team's second of delay", "radio.delay", "1", |s| {
        s.robots = 10_000;
        s.radio.delay = 1.0;
    });
    assert!(flight.accepts.contains("in flight"), "{flight}");
    let partition = |start: f64, end: f64, island: Vec<u32>| {
        move |s: &mut Scenario| s.radio.partitions.push(Partition { start, end, island: island.clone() })
    };
    let backwards = refused("ends before it starts", "radio.partitions[0].end", "2", partition(5.0, 2.0, vec![1]));
    assert!(backwards.accepts.contains("5 s"), "{backwards}");
    refused("unknown node", "radio.partitions[0].island", "99", partition(1.0, 2.0, vec![1, 99]));
    refused("node 0", "radio.partitions[0].island", "0", partition(1.0, 2.0, vec![0]));
    refused("NaN start", "radio.partitions[0].start", "NaN", partition(NAN, 2.0, vec![1]));
    refused("negative start", "radio.partitions[0].start", "-1", partition(-1.0, 2.0, vec![1]));
    refused("infinite end", "radio.partitions[0].end", "inf", partition(1.0, INF, vec![1]));
    // The Planner's base station is a node of the Planner's runs only.
    let station = vec![1, PLANNER_NODE.0];
    refused(
        "base station without a Planner",
        "radio.partitions[0].island",
        "65535",
        partition(1.0, 2.0, station.clone()),
    );
    let mut planner = base();
    planner.controller = Controller::Planner;
    planner.radio.partitions.push(Partition { start: 1.0, end: 2.0, island: station });
    planner.validate().expect("the Planner's base station is a node");
}

#[test]
fn kills_and_controller_tunables_out_of_bounds_are_named() {
    let kill = |at: f64, robot: Option<u32>| move |s: &mut Scenario| s.kills.push(Kill { at, robot });
    let e = refused("robot 99", "kills[0].robot", "99", kill(5.0, Some(99)));
    assert!(e.accepts.contains("1 to 3"), "{e}");
    refused("robot 0", "kills[0].robot", "0", kill(2.0, Some(0)));
    refused("negative instant", "kills[0].at", "-1", kill(-1.0, None));
    refused("NaN instant", "kills[0].at", "NaN", kill(NAN, None));
    refused("infinite instant", "kills[0].at", "inf", kill(INF, Some(1)));
    refused("more kills than robots", "kills", "4 kills", |s| {
        s.kills = vec![Kill { at: 1.0, robot: None }; 4];
    });
    refused("a robot killed twice", "kills[1].robot", "2", |s| {
        s.kills = vec![Kill { at: 1.0, robot: Some(2) }, Kill { at: 3.0, robot: Some(2) }];
    });

    refused("claims at 0 Hz", "controllers.claim_hz", "0", |s| s.controllers.claim_hz = 0.0);
    refused("NaN claims", "controllers.claim_hz", "NaN", |s| s.controllers.claim_hz = NAN);
    refused("plans at 0 Hz", "controllers.plan_hz", "0", |s| s.controllers.plan_hz = 0.0);
    refused("plans at 1e300 Hz", "controllers.plan_hz", "1e300", |s| s.controllers.plan_hz = 1e300);
    refused("NaN base station", "controllers.base_station", "[NaN, 1]", |s| {
        s.controllers.base_station = Some([NAN, 1.0])
    });
    refused("NaN eligibility threshold", "controllers.eligibility.threshold", "NaN", |s| {
        s.controllers.eligibility =
            ayllu::stdlib::Eligibility::OnChange { threshold: NAN, refresh: ayllu_core::Duration::from_millis(500) }
    });
}

/// Values that ran before and mean something still run: zeros that mean "none", every
/// controller, the largest team, the longest run the frames allow.
#[test]
fn what_ran_before_still_runs() {
    for c in Controller::ALL {
        let mut s = Scenario::paper(c, 3).duration(2.0);
        s.kills.push(Kill { at: 1.0, robot: None });
        s.validate().unwrap_or_else(|e| panic!("{}: {e}", c.name()));
        run(&s).unwrap_or_else(|e| panic!("{}: {e}", c.name()));
    }
    type Change = Box<dyn Fn(&mut Scenario)>;
    let zeros: Vec<(&str, Change)> = vec![
        ("no sonar beams", Box::new(|s| s.world.sonar_beams = 0)),
        ("sense every tick (0 counts as 1)", Box::new(|s| s.sense_every = 0)),
        ("a frame every tick", Box::new(|s| s.frame_dt = 0.0)),
        ("point robots", Box::new(|s| s.world.robot_radius = 0.0)),
        ("point targets", Box::new(|s| s.world.target_radius = 0.0)),
        ("blind camera", Box::new(|s| s.world.camera_fov = 0.0)),
        ("no sonar range", Box::new(|s| s.world.sonar_range = 0.0)),
        ("a target that counts for nothing", Box::new(|s| s.world.targets[3].priority = 0.0)),
        ("standing robots", Box::new(|s| s.world.max_speed = 0.0)),
        ("radio range 0", Box::new(|s| s.radio.range = Some(0.0))),
        ("a one-second tick", Box::new(|s| s.dt = 1.0)),
        ("every robot killed", Box::new(|s| s.kills = vec![Kill { at: 1.0, robot: None }; 3])),
        (
            "an empty partition",
            Box::new(|s| s.radio.partitions.push(Partition { start: 3.0, end: 3.0, island: vec![] })),
        ),
        ("a base station outside the room", Box::new(|s| s.controllers.base_station = Some([-100.0, 50.0]))),
        ("a kill after the end", Box::new(|s| s.kills.push(Kill { at: 100.0, robot: Some(1) }))),
    ];
    for (case, change) in zeros {
        let mut s = base().duration(3.0);
        change(&mut s);
        s.validate().unwrap_or_else(|e| panic!("{case}: {e}"));
        run(&s).unwrap_or_else(|e| panic!("{case}: {e}"));
    }
    // The largest team validates (not run here: minutes), as does the longest run at the
    // default frame period and a recorded paper run of an hour.
    Scenario::sized(Controller::Ble, 10_000, 1000, 1).validate().expect("the largest team");
    base().duration(1.9e6).validate().expect("9.5e6 frames");
    base().duration(3600.0).recorded().validate().expect("an hour recorded");
}

#[test]
fn files_are_refused_naming_the_field_nan_and_infinities_included() {
    let file = |body: &str| scenario_file::scenario(&format!("controller = \"BLE\"\nrobots = 3\ntargets = 4\n{body}"));
    for (body, needle) in [
        ("duration = nan", "duration: NaN is not a usable duration: must be finite and in (0, 1e9] s"),
        ("duration = inf", "duration: inf is not"),
        ("duration = -inf", "duration: -inf is not"),
        ("duration = 1e300", "duration: 1e300 is not"),
        ("duration = -5.0", "duration: -5 is not"),
        ("[world]\narena = [nan, 8.0]", "world.arena: [NaN, 8] is not a usable arena"),
        ("[world]\narena = [0.0, 0.0]", "world.arena: [0, 0]"),
        ("[world]\nsonar_beams = 100000000", "world.sonar_beams: 100000000"),
        ("[world]\ntargets = []", "world.targets: 0 targets"),
        ("[world]\ncamera_fov = -1.0", "world.camera_fov: -1"),
        ("[radio]\nrange = nan", "radio.range: NaN"),
        ("[radio]\nloss = 2.0", "radio.loss: 2 is not a usable probability: must be finite and in [0, 1]"),
        ("[radio]\ndelay = -1.0\njitter = -1.0", "radio.delay: -1"),
        ("[[radio.partitions]]\nstart = 5.0\nend = 2.0\nisland = [1, 99]", "radio.partitions[0].end: 2"),
        ("[[kills]]\nat = 5.0\nrobot = 99", "kills[0].robot: 99"),
        ("[[kills]]\nat = -1.0", "kills[0].at: -1"),
        ("[controllers]\nplan_hz = 0.0", "controllers.plan_hz: 0 is not a usable rate"),
        ("[controllers]\nclaim_hz = 0.0", "controllers.claim_hz: 0"),
        ("[controllers]\nbase_station = [inf, 1.0]", "controllers.base_station: [inf, 1]"),
    ] {
        let e = file(body).expect_err(body);
        assert!(e.contains(needle), "{body}: {e}");
    }
    for (text, needle) in [
        ("robots = 0", "robots: 0 is not a usable team: must be a whole number from 1 to 10000"),
        ("robots = 2.5", "robots: 2.5"),
        ("robots = -1", "robots: -1"),
        ("targets = 0", "targets: 0 is not a usable number of targets"),
        ("targets = 1000000000000", "targets: 1000000000000"),
        // A string is still no number, whatever it spells.
        ("duration = \"10\"", "does not fit"),
    ] {
        let e = scenario_file::scenario(text).expect_err(text);
        assert!(e.contains(needle), "{text}: {e}");
    }
}

#[test]
fn sweeps_check_every_cell_and_controller() {
    let e = scenario_file::sweep("seeds = 1\ncontrollers = []\nrobots = 2\n").unwrap_err();
    assert!(e.starts_with("controllers: [] names no controller"), "{e}");
    let e = scenario_file::sweep(
        "seeds = 1\ncontrollers = [\"BLE\"]\n[grid]\n\"world.arena\" = [[8.0, 8.0], [0.0, 0.0]]\n",
    )
    .unwrap_err();
    assert!(e.starts_with("cell2 (world.arena = [0.0,0.0]): world.arena: [0, 0] is not a usable arena"), "{e}");
    let e =
        scenario_file::sweep("seeds = 1\ncontrollers = [\"BLE\"]\n[grid]\n\"radio.loss\" = [0.1, nan]\n").unwrap_err();
    assert!(e.contains("radio.loss: NaN is not a usable probability"), "{e}");
    // A partition naming the base station: valid in the Planner's runs only.
    let station = "[[radio.partitions]]\nstart = 1.0\nend = 2.0\nisland = [1, 65535]\n";
    let e = scenario_file::sweep(&format!("compare = [\"Planner\", \"BLE\"]\n{station}")).unwrap_err();
    assert!(e.contains("radio.partitions[0].island: 65535"), "{e}");
    scenario_file::sweep(&format!("compare = [\"Planner\"]\n{station}")).expect("Planner only");
}

#[test]
fn the_example_files_are_within_bounds() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/sim");
    let mut seen = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("toml") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        // A sweep has seeds, a list of controllers or a grid; the rest are scenarios.
        let is_sweep = ["seeds", "compare", "controllers = [", "[grid]"].iter().any(|k| text.contains(k));
        let scenarios = match is_sweep {
            true => scenario_file::sweep(&text).map(|sw| sw.runs().into_iter().map(|(_, _, _, s)| s).collect()),
            false => scenario_file::scenario(&text).map(|s| vec![s]),
        };
        for s in scenarios.unwrap_or_else(|e| panic!("{}: {e}", path.display())) {
            s.validate().unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        }
        seen += 1;
    }
    assert!(seen >= 7, "{seen} example files");
}

/// A number for a field: mostly ordinary, sometimes anything (NaN, infinities, subnormals,
/// huge, negative), so that some scenarios are valid and run and the rest are refused.
fn value(ordinary: std::ops::Range<f64>) -> impl Strategy<Value = f64> {
    prop_oneof![
        60 => ordinary,
        1 => any::<f64>(),
        1 => prop_oneof![Just(0.0), Just(-1.0), Just(f64::NAN), Just(f64::INFINITY), Just(f64::NEG_INFINITY), Just(1e300)],
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// Any scenario made of arbitrary numbers is refused with an error naming a field, or
    /// builds and runs (a short time: 30 ticks) without a panic.
    #[test]
    fn arbitrary_numbers_are_refused_or_run(
        controller in 0..Controller::ALL.len(),
        arena in proptest::collection::vec(value(2.0..20.0), 2),
        world in proptest::collection::vec(value(0.0..6.0), 12),
        beams in prop_oneof![8 => 0usize..32, 1 => any::<usize>()],
        target in proptest::collection::vec(value(0.0..5.0), 2),
        radio in proptest::collection::vec(value(0.0..1.0), 4),
        times in proptest::collection::vec(value(0.0..20.0), 6),
        rates in proptest::collection::vec(value(0.1..5.0), 4),
        kill in prop_oneof![2 => Just(None), 6 => (1u32..4).prop_map(Some), 1 => any::<u32>().prop_map(Some)],
        island in proptest::collection::vec(prop_oneof![8 => 1u32..4, 1 => any::<u32>()], 0..3),
    ) {
        let mut s = Scenario::paper(Controller::ALL[controller], 1);
        let w = &mut s.world;
        w.arena = [arena[0], arena[1]];
        w.robot_radius = world[0] / 10.0;
        w.target_radius = world[1] / 10.0;
        w.max_speed = world[2];
        w.max_turn = world[3];
        w.camera_fov = world[4];
        w.camera_range = world[5];
        w.observe_range = world[6];
        w.sonar_range = world[7];
        w.sonar_noise = world[8] / 10.0;
        w.bearing_noise = world[9] / 10.0;
        w.miss_rate = world[10] / 10.0;
        w.focal = world[11] * 100.0;
        w.sonar_beams = beams;
        w.targets[0].priority = target[0];
        w.targets[1].speed = target[1];
        s.radio.loss = radio[0];
        s.radio.delay = radio[1] / 10.0;
        s.radio.jitter = radio[2] / 10.0;
        s.radio.range = (radio[3] != 0.0).then_some(radio[3] * 10.0);
        s.duration = times[0];
        s.dt = times[1] / 100.0;
        s.frame_dt = times[2] / 10.0;
        s.kills.push(Kill { at: times[3], robot: kill });
        s.radio.partitions.push(Partition { start: times[4], end: times[4] + times[5], island });
        s.controllers.claim_hz = rates[0];
        s.controllers.plan_hz = rates[1];
        s.controllers.base_station = Some([rates[2], rates[3]]);
        match Sim::new(&s) {
            Err(SimError::Scenario(e)) => {
                prop_assert!(s.validate().is_err());
                prop_assert!(e.to_string().starts_with(&format!("{}: ", e.field)), "{}", e);
            }
            Err(SimError::Node(e)) => prop_assert!(false, "a valid scenario failed to build: {e}"),
            Ok(mut sim) => {
                let mut ticks = 0;
                while !sim.done() && ticks < 30 {
                    sim.step().map_err(|e| TestCaseError::fail(e.to_string()))?;
                    ticks += 1;
                }
                let out = sim.finish();
                prop_assert!(out.metrics.a_w.is_finite(), "{:?}", out.metrics);
            }
        }
    }
}

#[test]
fn sized_allocates_nothing_beyond_the_bounds_and_validate_refuses_absurd_counts() {
    // `sized(.., usize::MAX)` used to collect usize::MAX target priorities before any check.
    let s = Scenario::sized(Controller::Ble, 3, usize::MAX, 1);
    assert_eq!(s.world.targets.len(), ayllu_sim::bounds::MAX_TARGETS + 1);
    let e = s.validate().unwrap_err().to_string();
    assert!(e.starts_with("world.targets: 1001 targets ") && e.contains("from 1 to 1000 targets"), "{e}");
    let e = Scenario::sized(Controller::Ble, usize::MAX, usize::MAX, 1).validate().unwrap_err().to_string();
    assert!(e.starts_with("robots: ") && e.contains("from 1 to 10000"), "{e}");
    // The room is sized from the capped counts: the arena is not what is refused.
    let e = Scenario::sized(Controller::Ble, 3, 1 << 40, 1).validate().unwrap_err().to_string();
    assert!(e.starts_with("world.targets"), "{e}");
    // try_sized refuses the counts as given, before anything is made.
    let e = Scenario::try_sized(Controller::Ble, 3, usize::MAX, 1).unwrap_err().to_string();
    assert!(e.starts_with(&format!("targets: {} ", usize::MAX)) && e.contains("from 1 to 1000 targets"), "{e}");
    let e = Scenario::try_sized(Controller::Ble, 0, 4, 1).unwrap_err().to_string();
    assert!(e.starts_with("robots: 0 "), "{e}");
    let ok = Scenario::try_sized(Controller::Ble, 10_000, 1000, 1).expect("the largest team");
    assert_eq!(ok, Scenario::sized(Controller::Ble, 10_000, 1000, 1));
    ok.validate().expect("valid");
}
