//! A fan-in rig for the port-kind tests (rule S3): `k` source behaviors `S0..S{k-1}`, each with
//! a Normal `Out` port, wired by Normal connections into one port `Agg.In` of the kind under
//! test; `Agg.In` is wired on to a Normal `Tap.In`, whose `accepted` count shows every value
//! `Agg.In` accepted and propagated (rule S5).
#![allow(dead_code)]

use ayllu_core::*;

pub const N: NodeId = NodeId(1);

pub fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

pub struct FanIn {
    pub node: NodeCore,
    /// `conns[i]` is the connection `S{i}.Out -> Agg.In`.
    pub conns: Vec<ConnectionId>,
    pub agg: PortRef,
    pub tap: PortRef,
}

impl FanIn {
    /// Build the rig with `Agg.In` declared by `spec` (its name is replaced by `In`).
    pub fn new(spec: PortSpec, k: usize) -> FanIn {
        FanIn::with_priorities(spec, &vec![0; k])
    }

    /// As [`FanIn::new`], with connection `i` carrying priority `prios[i]`.
    pub fn with_priorities(mut spec: PortSpec, prios: &[i32]) -> FanIn {
        let mut node = NodeCore::new(N);
        let default = spec.default.clone();
        let mut src = BehaviorClass::new("Src");
        src.port(PortSpec::new("Out", default.clone())).unwrap();
        let mut agg = BehaviorClass::new("Agg");
        spec.name = "In".into();
        agg.port(spec).unwrap();
        let mut tap = BehaviorClass::new("Tap");
        tap.port(PortSpec::new("In", default)).unwrap();
        node.define(src).unwrap();
        node.define(agg).unwrap();
        node.define(tap).unwrap();
        node.create("Agg", "Agg").unwrap();
        node.create("Tap", "Tap").unwrap();
        let mut conns = Vec::new();
        for (i, &priority) in prios.iter().enumerate() {
            let name = format!("S{i}");
            node.create("Src", &name).unwrap();
            let c = node
                .connect(
                    &Endpoint::local(&name, "Out"),
                    &Endpoint::local("Agg", "In"),
                    ConnectionKind::Normal,
                    ConnectOptions { priority },
                )
                .unwrap();
            conns.push(c);
        }
        node.connect(
            &Endpoint::local("Agg", "In"),
            &Endpoint::local("Tap", "In"),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )
        .unwrap();
        let agg = node.port("Agg", "In").unwrap();
        let tap = node.port("Tap", "In").unwrap();
        FanIn { node, conns, agg, tap }
    }

    /// Source `i` writes `v` at `t`; it reaches `Agg.In` along `conns[i]`.
    pub fn send(&mut self, i: usize, t: Instant, v: impl Into<Value>) {
        let out = self.node.port(&format!("S{i}"), "Out").unwrap();
        self.node.write(t, out, v).unwrap();
    }

    /// The `Source` that connection `i` stands for at `Agg.In`.
    pub fn source(&self, i: usize) -> Source {
        Source::connection(N, self.conns[i])
    }

    /// `Agg`'s own process writes `v` at `t` (source `n1/process`, priority 0).
    pub fn own(&mut self, t: Instant, v: impl Into<Value>) -> Result<(), Error> {
        self.node.write(t, self.agg, v)
    }

    pub fn read(&self) -> Value {
        self.node.read(self.agg).unwrap()
    }

    pub fn report(&self) -> PortReport {
        self.node.why("Agg", "In").unwrap()
    }

    pub fn supplier(&self) -> Option<Source> {
        self.report().supplier
    }

    /// How often `Agg.In` counted `cause`.
    pub fn dropped(&self, cause: DropCause) -> u64 {
        self.report().counters.get(cause)
    }

    /// How many values reached the tap, i.e. were accepted *and* propagated by `Agg.In`.
    pub fn propagated(&self) -> u64 {
        self.node.why("Tap", "In").unwrap().accepted
    }

    pub fn tap(&self) -> Value {
        self.node.read(self.tap).unwrap()
    }

    /// Let time pass to `t` (nothing is scheduled in the rig).
    pub fn at(&mut self, t: Instant) {
        self.node.poll(t);
    }
}
