//! The Zenoh peer of `make bench-peers`: one process of a pair, measuring what the other
//! peers measure (benches/peers/run): `pong` echoes every sample on `bench/ping` to
//! `bench/pong`; `ping` times round trips; `recv` counts samples on `bench/flow`; `send`
//! publishes them for a fixed time. Two peers in `peer` mode on 127.0.0.1, no scouting: the
//! `pong`/`recv` side listens on the endpoint given, the other connects to it. Samples are
//! express (not batched), over tcp:// (Zenoh's default link), congestion control Drop for the one-way flow
//! and Block for the round trip. Output lines are those of the other peers:
//! `rtt_ns <n> <n> ...` and `flow sent=<n>` / `flow received=<n> secs=<s>`.

use std::time::{Duration, Instant};

use zenoh::qos::CongestionControl;
use zenoh::{Config, Wait};

fn config(endpoint: &str, listen: bool) -> Config {
    let mut c = Config::default();
    c.insert_json5("mode", "\"peer\"").expect("mode");
    c.insert_json5("scouting/multicast/enabled", "false").expect("scouting");
    let key = if listen { "listen/endpoints" } else { "connect/endpoints" };
    c.insert_json5(key, &format!("[\"{endpoint}\"]")).expect("endpoint");
    if !listen {
        c.insert_json5("listen/endpoints", "[]").expect("listen");
    }
    c
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 5 {
        eprintln!("usage: zenoh-peer ping|pong|send|recv ENDPOINT PAYLOAD_BYTES COUNT_OR_SECONDS");
        std::process::exit(2);
    }
    let (mode, endpoint) = (args[1].as_str(), args[2].as_str());
    let size: usize = args[3].parse().expect("payload bytes");
    let amount: f64 = args[4].parse().expect("count or seconds");
    let listen = matches!(mode, "pong" | "recv");
    let session = zenoh::open(config(endpoint, listen)).wait().expect("open session");
    let payload = vec![7u8; size];
    match mode {
        "pong" => {
            let publisher = session
                .declare_publisher("bench/pong")
                .congestion_control(CongestionControl::Block)
                .express(true)
                .wait()
                .expect("publisher");
            let sub = session.declare_subscriber("bench/ping").wait().expect("subscriber");
            let give_up = Instant::now() + Duration::from_secs(120);
            let mut echoed = 0u64;
            while (echoed as f64) < amount && Instant::now() < give_up {
                match sub.recv_timeout(Duration::from_secs(5)) {
                    Ok(Some(sample)) => {
                        publisher.put(sample.payload().clone()).wait().expect("put");
                        echoed += 1;
                    }
                    _ => break,
                }
            }
        }
        "ping" => {
            let publisher = session
                .declare_publisher("bench/ping")
                .congestion_control(CongestionControl::Block)
                .express(true)
                .wait()
                .expect("publisher");
            let sub = session.declare_subscriber("bench/pong").wait().expect("subscriber");
            let rounds = amount as usize;
            let mut samples = Vec::with_capacity(rounds);
            // Until the pong's subscription has reached us, pings go nowhere: retry each.
            let mut i = 0;
            let give_up = Instant::now() + Duration::from_secs(120);
            while i < rounds && Instant::now() < give_up {
                let t0 = Instant::now();
                publisher.put(payload.clone()).wait().expect("put");
                if let Ok(Some(_)) = sub.recv_timeout(Duration::from_millis(200)) {
                    samples.push(t0.elapsed().as_nanos() as u64);
                    i += 1;
                }
            }
            let text: Vec<String> = samples.iter().map(|n| n.to_string()).collect();
            println!("rtt_ns {}", text.join(" "));
        }
        "recv" => {
            let sub = session.declare_subscriber("bench/flow").wait().expect("subscriber");
            let (mut received, mut first, mut last) = (0u64, None, Instant::now());
            let give_up = Instant::now() + Duration::from_secs(120);
            println!("ready");
            while Instant::now() < give_up {
                match sub.recv_timeout(Duration::from_millis(if received == 0 { 30_000 } else { 300 })) {
                    Ok(Some(_)) => {
                        let now = Instant::now();
                        first.get_or_insert(now);
                        received += 1;
                        last = now;
                    }
                    _ => break,
                }
            }
            let secs = first.map_or(0.0, |f| (last - f).as_secs_f64());
            println!("flow received={received} secs={secs:.6}");
        }
        "send" => {
            let publisher = session
                .declare_publisher("bench/flow")
                .congestion_control(CongestionControl::Drop)
                .express(true)
                .wait()
                .expect("publisher");
            // Give the route to the receiver's subscription a moment to be declared.
            std::thread::sleep(Duration::from_millis(500));
            let (start, mut sent) = (Instant::now(), 0u64);
            while start.elapsed().as_secs_f64() < amount {
                for _ in 0..64 {
                    publisher.put(payload.clone()).wait().expect("put");
                    sent += 1;
                }
            }
            println!("flow sent={sent}");
        }
        other => panic!("unknown mode {other}"),
    }
}
