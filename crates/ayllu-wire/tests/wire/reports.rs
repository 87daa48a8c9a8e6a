//! LIST/WHY reports survive the JSON round trip through REPLY parts, including floats JSON
//! cannot write as numbers (NaN, infinities) and reports that need several parts.

use ayllu_core::*;
use ayllu_wire::{reply_messages, ReplyAssembler, WireMessage};

fn round_trip(body: ReplyBody) -> ReplyBody {
    let parts = reply_messages(9, &Ok(body), 300, true).unwrap();
    let mut asm = ReplyAssembler::new();
    let mut out = None;
    for m in parts.into_iter().rev() {
        let WireMessage::Reply { part, parts, payload, .. } = m else { panic!("not a reply") };
        if let Some(r) = asm.push(part, parts, payload).unwrap() {
            out = Some(r.unwrap());
        }
    }
    out.expect("assembled")
}

#[test]
fn non_finite_floats_survive_a_why_report() {
    let mut node = NodeCore::new(NodeId(1));
    let mut c = BehaviorClass::new("C");
    c.port(PortSpec::new("X", 0.0)).unwrap();
    c.port(PortSpec::new("V", Value::vector(&[0.0]))).unwrap();
    node.define(c).unwrap();
    node.create("C", "B").unwrap();
    for (value, vector) in [(f64::NAN, [f64::INFINITY, 1.5]), (f64::NEG_INFINITY, [-0.0, f64::NAN])] {
        node.write_named(Instant::ZERO, "B", "X", value).unwrap();
        node.write_named(Instant::ZERO, "B", "V", Value::vector(&vector)).unwrap();
        let ReplyBody::Port(r) = round_trip(ReplyBody::Port(Box::new(node.why("B", "X").unwrap()))) else { panic!() };
        assert_eq!(r.value.as_float().unwrap().to_bits(), value.to_bits());
        let ReplyBody::Node(n) = round_trip(ReplyBody::Node(Box::new(node.report()))) else { panic!() };
        let v = n.behaviors[0].ports.iter().find(|p| p.name == "V").unwrap().value.clone();
        let got: Vec<u64> = v.as_vector().unwrap().iter().map(|x| x.to_bits()).collect();
        assert_eq!(got, vector.iter().map(|x| x.to_bits()).collect::<Vec<_>>());
    }
}
