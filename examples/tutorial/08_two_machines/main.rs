//! Tutorial 8, two machines, one program per robot (docs/tutorials/08-two-machines.md): the
//! same program runs on every robot, told only its id. Each robot's sonar drives the motor of
//! the other robot across the network, and each prints what its own motor receives, from whom,
//! then `why`. The nodes find each other from `AYLLU_URL` (the subnet form on robots; with it
//! unset, the machine-local default), on the real clock.
//!
//! Run, on machine A and machine B of one subnet:
//!
//! ```sh
//! export AYLLU_URL='udp://0.0.0.0:0?discovery=239.255.65.89:7390&ttl=1'
//! cargo run -p ayllu --example tutorial_08_two_machines -- 1    # on A
//! cargo run -p ayllu --example tutorial_08_two_machines -- 2    # on B
//! ```
//!
//! Exits 0 once the other robot's values have driven this robot's motor, non-zero (naming the
//! likely cause) if none arrived within the run (`--for SECONDS`, 10 by default).

use ayllu::*;

/// The other robot of the two (ids 1 and 2): the one whose motor this robot's sonar drives,
/// and whose sonar drives this robot's motor.
pub fn partner(id: u32) -> u32 {
    3 - id
}

/// What robot `id`'s sonar reads: a distinct constant per robot, so each motor's value says
/// which robot it came from.
pub fn range_of(id: u32) -> f64 {
    0.5 + 0.1 * f64::from(id)
}

/// One robot: a sonar writing `Range` at 20 Hz, and a motor whose `Speed` goes stale 300 ms
/// after its last command (rule S4), so a robot that loses its partner sees it at once.
fn robot(id: u32, url: &str) -> Result<Node, Box<dyn std::error::Error>> {
    let mut node = Node::open(NodeId(id), url)?;
    let mut sonar = BehaviorClass::new("Sonar");
    let range = sonar.port(PortSpec::new("Range", 0.0))?;
    let reading = range_of(id);
    sonar.every_hz("Ping", 20.0, move |ctx| {
        let _ = ctx.write(range, reading);
    })?;
    let mut motor = BehaviorClass::new("Motor");
    motor.port(PortSpec::new("Speed", 0.0).lifespan(Duration::from_millis(300)))?;
    node.define(sonar)?;
    node.define(motor)?;
    node.create("Sonar", "SONAR")?;
    node.create("Motor", "MOTOR")?;
    // A connection to a port of another robot, by node id: no address. Until the partner
    // greets, the transport holds only the newest value (a port's value is worth only its
    // newest) and sends it when the partner is heard.
    node.connect(
        &Endpoint::local("SONAR", "Range"),
        &Endpoint::node(NodeId(partner(id)), "MOTOR", "Speed"),
        ConnectionKind::Normal,
    )?;
    Ok(node)
}

/// The program: robot `id` on `url` for `seconds` of the real clock, printing as it goes. Fails
/// naming what did not happen.
pub fn run(id: u32, url: &str, seconds: f64) -> Result<(), Box<dyn std::error::Error>> {
    let mut node = robot(id, url)?;
    let other = partner(id);
    println!("robot {id} at {}, its sonar drives robot {other}'s motor", node.address().unwrap_or_default());
    let start = std::time::Instant::now();
    let (mut next_print, mut heard, mut received) = (1.0, false, 0u32);
    while start.elapsed().as_secs_f64() < seconds {
        node.run_for(std::time::Duration::from_millis(10));
        let t = start.elapsed().as_secs_f64();
        if !heard {
            if let Some(peer) = node.peers().into_iter().find(|p| p.node == NodeId(other)) {
                heard = true;
                println!("{t:4.1} s  heard robot {other} at {}", peer.addr);
            }
        }
        if t >= next_print {
            next_print += 1.0;
            let why = node.why("MOTOR", "Speed")?;
            let by = why.supplier.map_or("nobody".to_owned(), |s| s.to_string());
            let value = if why.fresh { format!("{:.1}", why.value.as_float().unwrap_or(0.0)) } else { "stale".into() };
            println!("{t:4.1} s  MOTOR.Speed = {value} from {by}");
            if why.fresh && by.starts_with(&format!("n{other}/")) {
                received += 1;
            }
        }
    }
    if received == 0 {
        return Err(format!(
            "nothing from robot {other} in {seconds} s: is it running, with the same AYLLU_URL \
             (ttl=1 across machines, the same team= and key=)? docs/troubleshooting.md, by symptom"
        )
        .into());
    }
    print!("{}", node.why("MOTOR", "Speed")?);
    Ok(())
}

/// `ID [--for SECONDS]`, ID 1 or 2.
fn arguments() -> Result<(u32, f64), String> {
    let usage = "usage: tutorial_08_two_machines ID [--for SECONDS] (ID: 1 or 2)";
    let args: Vec<String> = std::env::args().skip(1).collect();
    let id = args.first().and_then(|a| a.parse().ok()).filter(|id| [1, 2].contains(id)).ok_or(usage)?;
    let seconds = match args.get(1).map(String::as_str) {
        None => 10.0,
        Some("--for") => args.get(2).and_then(|s| s.parse().ok()).filter(|&s: &f64| s > 0.0).ok_or(usage)?,
        Some(_) => return Err(usage.into()),
    };
    Ok((id, seconds))
}

#[allow(dead_code)] // the tests call `run`
fn main() {
    let result = arguments().map_err(Into::into).and_then(|(id, seconds)| run(id, &default_url(), seconds));
    if let Err(e) = result {
        eprintln!("{e}");
        std::process::exit(1);
    }
}
