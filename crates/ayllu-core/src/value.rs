//! Values a register holds (rule S1).
//!
//! A port holds exactly one [`Value`] of the [`ValueType`] it was declared with. Scalars are
//! plain data; text, bytes and vectors are reference-counted, so a value travelling along a
//! connection is copied or has a count bumped — propagation never allocates (design §6).
//! Values are never coerced: an `Int` is not a `Float`.

use core::cmp::Ordering;
use core::fmt;
use std::sync::Arc;

/// The longest vector a message to another node carries: the wire counts a vector's numbers
/// in one byte (spec/protocol.md, "Value"). A connection to another node from a port that
/// holds a longer one is refused ([`crate::Error::TooLongForNetwork`], docs/semantics.md
/// D-S10.7); locally a vector has any length.
pub const MAX_NETWORK_VECTOR: usize = 255;

/// The type of a register, fixed when it is declared.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum ValueType {
    /// `true` or `false` (ordered `false < true` in Max and Min ports).
    Bool,
    /// A signed 64-bit integer; wraps in a Sum port (D3.5).
    Int,
    /// A 64-bit IEEE 754 float.
    Float,
    /// UTF-8 text.
    Text,
    /// Opaque bytes.
    Bytes,
    /// A short vector of floats: a pose, a velocity, a bearing list.
    Vector,
}

/// One register value.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Value {
    /// A bool.
    Bool(bool),
    /// An integer; never turned into a float or back (rule S1).
    Int(i64),
    /// A float. Max and Min compare in IEEE total order (`-0.0 < 0.0`, D3.4); NaN is refused by
    /// Max, Min and Sum ports (D3.6).
    Float(#[cfg_attr(feature = "serde", serde(with = "json_float"))] f64),
    /// Text, reference-counted so propagation only bumps a count.
    Text(Arc<str>),
    /// Bytes, reference-counted like text.
    Bytes(Arc<[u8]>),
    /// A float vector of any length (a pose, a velocity); a Sum port fixes its length by its
    /// default (D3.5).
    Vector(#[cfg_attr(feature = "serde", serde(with = "json_floats"))] Arc<[f64]>),
}

/// JSON has no NaN or infinities; reports (LIST, WHY) must still carry every float a port
/// can hold, so non-finite floats are written as the strings "NaN", "inf" and "-inf".
#[cfg(feature = "serde")]
mod json_float {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    #[derive(Serialize, Deserialize)]
    #[serde(untagged)]
    pub(super) enum Repr<'a> {
        Number(f64),
        Word(std::borrow::Cow<'a, str>),
    }

    pub(super) fn to_repr(x: f64) -> Repr<'static> {
        if x.is_finite() {
            Repr::Number(x)
        } else if x.is_nan() {
            Repr::Word("NaN".into())
        } else if x > 0.0 {
            Repr::Word("inf".into())
        } else {
            Repr::Word("-inf".into())
        }
    }

    pub(super) fn from_repr<E: serde::de::Error>(r: Repr<'_>) -> Result<f64, E> {
        match r {
            Repr::Number(x) => Ok(x),
            Repr::Word(w) => match &*w {
                "NaN" => Ok(f64::NAN),
                "inf" => Ok(f64::INFINITY),
                "-inf" => Ok(f64::NEG_INFINITY),
                other => Err(E::custom(format!("`{other}` is not a float"))),
            },
        }
    }

    pub fn serialize<S: Serializer>(x: &f64, s: S) -> Result<S::Ok, S::Error> {
        to_repr(*x).serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        from_repr(Repr::deserialize(d)?)
    }
}

/// [`json_float`] for every element of a vector.
#[cfg(feature = "serde")]
mod json_floats {
    use std::sync::Arc;

    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    use super::json_float::{from_repr, to_repr, Repr};

    pub fn serialize<S: Serializer>(v: &Arc<[f64]>, s: S) -> Result<S::Ok, S::Error> {
        v.iter().map(|x| to_repr(*x)).collect::<Vec<_>>().serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Arc<[f64]>, D::Error> {
        Vec::<Repr<'de>>::deserialize(d)?.into_iter().map(from_repr).collect()
    }
}

impl Value {
    /// The value's type: a port refuses values of any other (rule S1).
    pub fn ty(&self) -> ValueType {
        match self {
            Value::Bool(_) => ValueType::Bool,
            Value::Int(_) => ValueType::Int,
            Value::Float(_) => ValueType::Float,
            Value::Text(_) => ValueType::Text,
            Value::Bytes(_) => ValueType::Bytes,
            Value::Vector(_) => ValueType::Vector,
        }
    }
    /// A text value (copies `s` once; propagating it then only bumps a count).
    pub fn text(s: &str) -> Value {
        Value::Text(Arc::from(s))
    }
    /// A bytes value (copies `b` once).
    pub fn bytes(b: &[u8]) -> Value {
        Value::Bytes(Arc::from(b))
    }
    /// A vector value (copies `v` once).
    pub fn vector(v: &[f64]) -> Value {
        Value::Vector(Arc::from(v))
    }
    /// The bool, or `None` for another type (never coerced).
    pub fn as_bool(&self) -> Option<bool> {
        match self {
            Value::Bool(b) => Some(*b),
            _ => None,
        }
    }
    /// The integer, or `None` for another type (a float is not converted).
    pub fn as_int(&self) -> Option<i64> {
        match self {
            Value::Int(i) => Some(*i),
            _ => None,
        }
    }
    /// The float, or `None` for another type (an integer is not converted).
    pub fn as_float(&self) -> Option<f64> {
        match self {
            Value::Float(x) => Some(*x),
            _ => None,
        }
    }
    /// The text, or `None` for another type.
    pub fn as_text(&self) -> Option<&str> {
        match self {
            Value::Text(s) => Some(s),
            _ => None,
        }
    }
    /// The bytes, or `None` for another type.
    pub fn as_bytes(&self) -> Option<&[u8]> {
        match self {
            Value::Bytes(b) => Some(b),
            _ => None,
        }
    }
    /// The vector's elements, or `None` for another type.
    pub fn as_vector(&self) -> Option<&[f64]> {
        match self {
            Value::Vector(v) => Some(v),
            _ => None,
        }
    }
    /// True for a float NaN, which has no place in an order and is refused by Max/Min/Sum.
    pub fn is_nan(&self) -> bool {
        matches!(self, Value::Float(x) if x.is_nan())
    }
    /// The order Max and Min ports use; `None` for types without one (text, bytes, vectors)
    /// or when the two values differ in type. Floats use the IEEE total order, so `-0.0 < 0.0`
    /// and equal means bit-identical: the value a port keeps never depends on arrival order.
    pub fn order(&self, other: &Value) -> Option<Ordering> {
        match (self, other) {
            (Value::Bool(a), Value::Bool(b)) => Some(a.cmp(b)),
            (Value::Int(a), Value::Int(b)) => Some(a.cmp(b)),
            (Value::Float(a), Value::Float(b)) => Some(a.total_cmp(b)),
            _ => None,
        }
    }
    /// The zero of a type, used as the default when a register is declared by type only.
    pub fn zero(ty: ValueType) -> Value {
        match ty {
            ValueType::Bool => Value::Bool(false),
            ValueType::Int => Value::Int(0),
            ValueType::Float => Value::Float(0.0),
            ValueType::Text => Value::text(""),
            ValueType::Bytes => Value::bytes(&[]),
            ValueType::Vector => Value::vector(&[]),
        }
    }
}

impl ValueType {
    /// The type's name as errors, reports and the CLI print it (`float`).
    pub fn name(self) -> &'static str {
        match self {
            ValueType::Bool => "bool",
            ValueType::Int => "int",
            ValueType::Float => "float",
            ValueType::Text => "text",
            ValueType::Bytes => "bytes",
            ValueType::Vector => "vector",
        }
    }
}

impl fmt::Display for ValueType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Bool(b) => write!(f, "{b}"),
            Value::Int(i) => write!(f, "{i}"),
            Value::Float(x) => write!(f, "{x}"),
            Value::Text(s) => write!(f, "{s:?}"),
            Value::Bytes(b) => {
                f.write_str("0x")?;
                for byte in b.iter() {
                    write!(f, "{byte:02x}")?;
                }
                Ok(())
            }
            Value::Vector(v) => {
                f.write_str("[")?;
                for (i, x) in v.iter().enumerate() {
                    if i > 0 {
                        f.write_str(", ")?;
                    }
                    write!(f, "{x}")?;
                }
                f.write_str("]")
            }
        }
    }
}

impl From<bool> for Value {
    fn from(b: bool) -> Value {
        Value::Bool(b)
    }
}
impl From<i64> for Value {
    fn from(i: i64) -> Value {
        Value::Int(i)
    }
}
impl From<i32> for Value {
    fn from(i: i32) -> Value {
        Value::Int(i.into())
    }
}
impl From<f64> for Value {
    fn from(x: f64) -> Value {
        Value::Float(x)
    }
}
impl From<&str> for Value {
    fn from(s: &str) -> Value {
        Value::text(s)
    }
}
impl From<String> for Value {
    fn from(s: String) -> Value {
        Value::Text(Arc::from(s))
    }
}
impl From<&[f64]> for Value {
    fn from(v: &[f64]) -> Value {
        Value::vector(v)
    }
}
impl From<Vec<f64>> for Value {
    fn from(v: Vec<f64>) -> Value {
        Value::Vector(Arc::from(v))
    }
}
