//! Examples run as tests: the README's demo must keep showing what it claims to show.

#[path = "../../../examples/rust/cross_subsumption.rs"]
mod cross_subsumption;

#[test]
fn cross_subsumption_demo_shows_claims_and_takeover() {
    let out = cross_subsumption::run(20);
    assert!(!out.contains("warning"), "{out}");
    // Settled claims before the kill (S11): one robot per target.
    for line in ["T1 now claimed by robot 1", "T2 now claimed by robot 2", "T3 now claimed by robot 3"] {
        assert!(out.contains(line), "missing `{line}` in\n{out}");
    }
    // Robot 1 stops at 10 s; its target is taken over by robot 2 (leases lapse).
    let kill = out.find("robot 1 stops").expect("kill line");
    assert!(out[kill..].contains("T1 now claimed by robot 2"), "{out}");
    let last = out.lines().last().unwrap();
    assert!(last.starts_with(" 20.00 | (dead)  OBS1    OBS3"), "last line: {last}\n{out}");
}
