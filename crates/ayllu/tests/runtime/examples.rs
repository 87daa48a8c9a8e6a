//! Examples run as tests: each must keep showing what its header says it shows.

#[path = "../../../../examples/rust/cross_subsumption.rs"]
mod cross_subsumption;

#[path = "../../../../examples/rust/two_nodes_udp.rs"]
#[allow(dead_code)] // its `main` is for `cargo run --example`
mod two_nodes_udp;

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

#[test]
fn two_nodes_over_udp_the_sonar_drives_the_motor_until_the_joystick_overrides_it() {
    // Robot 1's sonar (n1, along its remote connection) and robot 2's joystick (n2, its local
    // override-in) each supplied the motor at some instant: the value crossed real sockets,
    // and the override took the port while the operator held the stick.
    let out = two_nodes_udp::run(3.0).unwrap();
    let seen = out.lines().find(|l| l.starts_with("suppliers seen:")).expect("summary line");
    assert!(seen.contains("n1/c"), "the sonar's values crossed the network: {out}");
    assert!(seen.contains("n2/c"), "the joystick overrode them: {out}");
    assert!(out.contains("n2:MOTOR.Speed (normal float)"), "why is printed: {out}");
}
