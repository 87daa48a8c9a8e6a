//! One message's values, a [`Sample`]: one per leaf of its type, read and written through a
//! [`FieldRef`] as Ayllu values.
//!
//! Promise: what is written is what is sent. [`Sample::set`] refuses a value the field cannot
//! hold and rounds floats to the field's width, so [`Sample::get`] returns what subscribers
//! will receive, and a sample's values always fit its type (which encoding relies on).

use std::fmt;
use std::sync::Arc;

use ayllu_core::{Value, ValueType};

use super::field::{FieldRef, Leaf};
use super::schema::{MessageType, Prim, Real, Ty, QUATERNION};

impl MessageType {
    /// A sample with every number zero, every string and sequence empty, and every quaternion
    /// the identity (`w = 1`, as ROS 2 declares it), ready to be filled with [`Sample::set`].
    pub fn default_sample(&self) -> Sample {
        fn fill(m: &MessageType, out: &mut Vec<Slot>) {
            for f in m.fields {
                out.push(match f.ty {
                    Ty::Struct(inner) => {
                        fill(inner, out);
                        continue;
                    }
                    Ty::Prim(Prim::Bool) => Slot::Bool(false),
                    Ty::Prim(Prim::Real(_)) => Slot::Float(0.0),
                    Ty::Prim(_) => Slot::Int(0),
                    Ty::Text => Slot::Text(Arc::from("")),
                    Ty::Seq(_) => Slot::Floats(Arc::from(Vec::new())),
                    Ty::Array(_, n) => Slot::Floats(Arc::from(vec![0.0; n])),
                    Ty::Structs(_) => Slot::Records(Vec::new()),
                });
            }
            if m.name == QUATERNION.name {
                if let Some(Slot::Float(w)) = out.last_mut() {
                    *w = 1.0;
                }
            }
        }
        let mut slots = Vec::with_capacity(self.slots());
        fill(self, &mut slots);
        Sample { ty: self.this, slots }
    }
}

/// One message's values: one per leaf of its type, in layout order.
#[derive(Clone, Debug, PartialEq)]
pub struct Sample {
    pub(super) ty: &'static MessageType,
    pub(super) slots: Vec<Slot>,
}

/// One leaf's value. Integers of every width are kept as `i64` and floats as `f64`, always
/// within the field's range and (for `float32`) exactly representable in it.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Slot {
    Bool(bool),
    Int(i64),
    Float(f64),
    Text(Arc<str>),
    Floats(Arc<[f64]>),
    /// A sequence of messages: each element's slots.
    Records(Vec<Vec<Slot>>),
}

impl Sample {
    /// The message type this is a sample of.
    pub fn message_type(&self) -> &'static MessageType {
        self.ty
    }

    /// The leaf's value: a bool, an integer, a float, text, or a vector for numeric arrays;
    /// `None` only for a field of another message type.
    pub fn get(&self, f: &FieldRef) -> Option<Value> {
        if f.ty != self.ty {
            return None;
        }
        if f.leaf == Leaf::Yaw {
            return self.quaternion(f.index).map(|q| Value::Float(yaw(q)));
        }
        Some(match self.slots.get(f.index)? {
            Slot::Bool(b) => Value::Bool(*b),
            Slot::Int(i) => Value::Int(*i),
            Slot::Float(x) => Value::Float(*x),
            Slot::Text(s) => Value::Text(s.clone()),
            Slot::Floats(xs) => Value::Vector(xs.clone()),
            Slot::Records(_) => return None,
        })
    }

    /// Writes the leaf, converting `v` to the field's type: a float to `float32` (rounded) or
    /// `float64`, an integer or bool to any integer width that holds it, an integer to a float,
    /// text to a string, a vector to a numeric sequence (or to a fixed array of its exact
    /// length). A yaw rewrites the whole quaternion as the rotation about z alone. Anything
    /// else is refused and leaves the sample unchanged.
    pub fn set(&mut self, f: &FieldRef, v: &Value) -> Result<(), SetError> {
        if f.ty != self.ty {
            return Err(SetError::OtherMessage { field_of: f.ty.name, sample_of: self.ty.name });
        }
        let wrong_type = || SetError::WrongType { field: f.leaf.to_string(), value: v.ty() };
        let out_of_range = || SetError::OutOfRange { field: f.leaf.to_string(), value: v.to_string() };
        let number = match *v {
            Value::Float(x) => Some(x),
            Value::Int(i) => Some(i as f64),
            _ => None,
        };
        let slot = match (f.leaf, v, number) {
            (Leaf::Yaw, _, Some(yaw)) if yaw.is_finite() => {
                let (sin, cos) = (yaw / 2.0).sin_cos();
                let quaternion = self.slots.get_mut(f.index..f.index + 4).ok_or_else(wrong_type)?;
                quaternion.clone_from_slice(&[0.0, 0.0, sin, cos].map(Slot::Float));
                return Ok(());
            }
            (Leaf::Yaw, _, Some(_)) => return Err(out_of_range()),
            (Leaf::Prim(Prim::Real(r)), _, Some(x)) => Slot::Float(to_real(r, x).ok_or_else(out_of_range)?),
            (Leaf::Prim(Prim::Bool), Value::Bool(b), _) => Slot::Bool(*b),
            (Leaf::Prim(p), Value::Int(i), _) if p != Prim::Bool && !fits(p, *i) => return Err(out_of_range()),
            (Leaf::Prim(p), Value::Int(i), _) if p != Prim::Bool => Slot::Int(*i),
            (Leaf::Prim(p), Value::Bool(b), _) if fits(p, 1) => Slot::Int(i64::from(*b)),
            (Leaf::Text, Value::Text(s), _) => Slot::Text(s.clone()),
            (Leaf::Array(_, n), Value::Vector(xs), _) if xs.len() != n => {
                return Err(SetError::WrongLength { expected: n, got: xs.len() })
            }
            (Leaf::Seq(Real::F64) | Leaf::Array(Real::F64, _), Value::Vector(xs), _) => Slot::Floats(xs.clone()),
            (Leaf::Seq(r) | Leaf::Array(r, _), Value::Vector(xs), _) => Slot::Floats(
                xs.iter().map(|x| to_real(r, *x)).collect::<Option<Arc<[f64]>>>().ok_or_else(out_of_range)?,
            ),
            _ => return Err(wrong_type()),
        };
        *self.slots.get_mut(f.index).ok_or_else(wrong_type)? = slot;
        Ok(())
    }

    fn quaternion(&self, at: usize) -> Option<[f64; 4]> {
        match self.slots.get(at..at + 4)? {
            [Slot::Float(x), Slot::Float(y), Slot::Float(z), Slot::Float(w)] => Some([*x, *y, *z, *w]),
            _ => None,
        }
    }
}

/// `x` at the field's width; `None` for a finite number a `float32` would make infinite.
fn to_real(r: Real, x: f64) -> Option<f64> {
    match r {
        Real::F64 => Some(x),
        Real::F32 => {
            let y = x as f32;
            (y.is_finite() || !x.is_finite()).then_some(f64::from(y))
        }
    }
}

fn fits(p: Prim, i: i64) -> bool {
    match p {
        Prim::U8 => u8::try_from(i).is_ok(),
        Prim::I32 => i32::try_from(i).is_ok(),
        Prim::U32 => u32::try_from(i).is_ok(),
        Prim::I64 => true,
        Prim::Bool | Prim::Real(_) => false,
    }
}

/// The rotation about z, from any quaternion, normalized or not (both terms scale by |q|²).
fn yaw([x, y, z, w]: [f64; 4]) -> f64 {
    (2.0 * (w * z + x * y)).atan2(w * w + x * x - y * y - z * z)
}

/// Why [`Sample::set`] refused a value.
#[derive(Clone, Debug, PartialEq)]
pub enum SetError {
    /// The value's type does not convert to the field's (a float into an `int32`, text into
    /// a `float64[]`).
    WrongType {
        /// The field's type, as a `.msg` file spells it.
        field: String,
        /// The type of the value offered.
        value: ValueType,
    },
    /// A number the field cannot hold: 3e9 into an `int32`, -1 into a `uint8`, 1e39 into a
    /// `float32`, a non-finite yaw.
    OutOfRange {
        /// The field's type, as a `.msg` file spells it.
        field: String,
        /// The value offered.
        value: String,
    },
    /// A vector of another length for a fixed-size array.
    WrongLength {
        /// The array's length.
        expected: usize,
        /// The vector's length.
        got: usize,
    },
    /// The field was resolved on another message type than the sample's.
    OtherMessage {
        /// The field's message type.
        field_of: &'static str,
        /// The sample's message type.
        sample_of: &'static str,
    },
}

impl fmt::Display for SetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SetError::WrongType { field, value } => write!(f, "a {value} cannot go into a {field} field"),
            SetError::OutOfRange { field, value } => write!(f, "{value} is out of range for a {field} field"),
            SetError::WrongLength { expected, got } => {
                write!(f, "a vector of {got} cannot go into an array of exactly {expected}")
            }
            SetError::OtherMessage { field_of, sample_of } => {
                write!(f, "a field of {field_of} cannot be set in a {sample_of}")
            }
        }
    }
}

impl std::error::Error for SetError {}
