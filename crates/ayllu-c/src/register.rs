//! The registers of a behavior class as C names them: which port, slot or monostable a name
//! stands for, fixed once when the class is defined. The class builder (`class.rs`) fills the
//! table and the process context (`process.rs`) looks names up in it, so it sits below both.
//!
//! Promise: the paper's `BLE_Local`, `BLE_Inhibit` and `BLE_Best` name the runtime's implicit
//! BLE ports everywhere a register or port name comes from C.

use std::collections::HashMap;

use ayllu_core::BehaviorClass;

/// What a name in a class stands for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Register {
    Port(u16),
    Slot(u16),
    Mono(u16),
}

/// A class's register names, shared by its processes (fixed when the class is defined).
#[derive(Debug, Default)]
pub(crate) struct Registers {
    names: HashMap<String, Register>,
    pub(crate) ports: usize,
    pub(crate) slots: usize,
    pub(crate) monos: usize,
}

impl Registers {
    pub(crate) fn of(class: &BehaviorClass) -> Registers {
        let mut names = HashMap::new();
        for (i, p) in class.ports().iter().enumerate() {
            names.insert(p.name.clone(), Register::Port(i as u16));
        }
        for (i, s) in class.slots().iter().enumerate() {
            names.insert(s.name.clone(), Register::Slot(i as u16));
        }
        for (i, m) in class.monostables().iter().enumerate() {
            names.insert(m.clone(), Register::Mono(i as u16));
        }
        Registers { names, ports: class.ports().len(), slots: class.slots().len(), monos: class.monostables().len() }
    }

    /// The register `name` stands for (the paper's `BLE_Local`, `BLE_Inhibit`, `BLE_Best` name
    /// the implicit ports `Local`, `Inhibit`, `Best`).
    pub(crate) fn get(&self, name: &str) -> Option<Register> {
        self.names.get(register_name(name)).copied()
    }
}

/// The runtime's name for a register or port named from C: the paper's `BLE_` prefix on the
/// implicit BLE ports is dropped.
pub(crate) fn register_name(name: &str) -> &str {
    match name {
        "BLE_Local" => ayllu_core::LOCAL,
        "BLE_Inhibit" => ayllu_core::INHIBIT,
        "BLE_Best" => ayllu_core::BEST,
        other => other,
    }
}
