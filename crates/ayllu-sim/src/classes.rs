//! The behavior classes a simulated team shares.
//!
//! What it is for: every robot of a scenario instantiates the same classes (VISION, SONAR and
//! BASE for its body; SafeVelocity, RandomWander, Observer, ... for its controller), built
//! from the same arguments. A class is immutable once defined (its processes are `Fn`; what
//! they remember lives in the behavior's ports and slots), so [`SharedClasses`] builds each
//! one once and defines that one `Arc` on every robot's node.
//!
//! Why: a process's closure and a class's port specifications are read when its node runs.
//! Built once per robot, a team of a thousand keeps a thousand copies of each, one more
//! place in memory per process that every robot's visit fetches anew; shared, the copies a
//! tick reads stay in the cache from one robot to the next.
//!
//! What it promises: a node built with shared classes behaves exactly as one built with its
//! own (the same class, the same behaviors, the same run bit for bit; `speed hashes` and the
//! scenario tests check it). A class is keyed by its name, so one `SharedClasses` serves one
//! scenario: the same name must always be built from the same arguments (debug builds check
//! the name).

use std::collections::HashMap;
use std::sync::Arc;

use ayllu_core::{BehaviorClass, Error, NodeCore};

/// Classes built once and defined on many nodes (see the module docs).
#[derive(Default)]
pub struct SharedClasses {
    classes: HashMap<&'static str, Arc<BehaviorClass>>,
}

impl SharedClasses {
    /// No class built yet.
    pub fn new() -> SharedClasses {
        SharedClasses::default()
    }

    /// Define class `name` on `node`: the copy built for an earlier node, else `make()`'s,
    /// kept for the next node. `make` must build a class called `name`.
    pub fn define(
        &mut self,
        node: &mut NodeCore,
        name: &'static str,
        make: impl FnOnce() -> Result<BehaviorClass, Error>,
    ) -> Result<(), Error> {
        let class = match self.classes.get(name) {
            Some(class) => class.clone(),
            None => {
                let class = Arc::new(make()?);
                debug_assert_eq!(class.name(), name, "a shared class is kept under its own name");
                self.classes.insert(name, class.clone());
                class
            }
        };
        node.define(class)
    }

    /// How many classes have been built.
    pub fn len(&self) -> usize {
        self.classes.len()
    }

    /// Whether none has been built yet.
    pub fn is_empty(&self) -> bool {
        self.classes.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ayllu_core::{NodeId, PortSpec};

    #[test]
    fn a_class_is_built_once_and_defined_on_every_node() {
        let mut shared = SharedClasses::new();
        let mut built = 0;
        let mut nodes: Vec<NodeCore> = (1..=3).map(|i| NodeCore::new(NodeId(i))).collect();
        for node in &mut nodes {
            shared
                .define(node, "Gauge", || {
                    built += 1;
                    let mut c = BehaviorClass::new("Gauge");
                    c.port(PortSpec::new("Level", 0.0))?;
                    Ok(c)
                })
                .unwrap();
            node.create("Gauge", "G").unwrap();
        }
        assert_eq!(built, 1);
        assert_eq!(shared.len(), 1);
        // Each node has its own behavior (its own port state) over the one class.
        let p = nodes[0].port("G", "Level").unwrap();
        nodes[0].write(ayllu_core::Instant::ZERO, p, 2.5).unwrap();
        assert_eq!(nodes[0].read(p).unwrap(), ayllu_core::Value::Float(2.5));
        let q = nodes[1].port("G", "Level").unwrap();
        assert_eq!(nodes[1].read(q).unwrap(), ayllu_core::Value::Float(0.0));
    }

    #[test]
    fn a_failed_build_is_not_kept() {
        let mut shared = SharedClasses::new();
        let mut node = NodeCore::new(NodeId(1));
        let err = shared.define(&mut node, "Bad", || Err(Error::EmptyName { what: "behavior class" }));
        assert!(err.is_err());
        assert!(shared.is_empty());
        assert!(!node.has_class("Bad"));
    }
}
