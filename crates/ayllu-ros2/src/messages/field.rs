//! Field paths: a dotted path such as `pose.pose.position.x`, resolved once when a mapping
//! file is loaded into a [`FieldRef`], which then reads or writes that one leaf of any sample.
//!
//! Promise: a path that names no leaf is refused with the nearest leaf as a suggestion, and a
//! path to a whole message with the leaves under it, so a mapping file's mistake comes with
//! its fix.

use std::fmt;

use super::schema::{MessageType, Prim, Real, Ty, QUATERNION};

impl MessageType {
    /// Resolves a dotted path to one leaf: `"ranges"`, `"pose.pose.position.x"`,
    /// `"header.stamp.sec"`. Below every `geometry_msgs/msg/Quaternion` there is also the
    /// virtual leaf `yaw` (`"pose.pose.orientation.yaw"`), read from the quaternion and written
    /// as the rotation about z alone.
    ///
    /// A path that names nothing gets the nearest leaf as a suggestion; a path to a message
    /// rather than a leaf is told the leaves under it.
    pub fn field(&self, path: &str) -> Result<FieldRef, FieldError> {
        let (mut within, mut fields, mut index) = (self.name, self.fields, 0);
        let mut segments = path.split('.').peekable();
        while let Some(segment) = segments.next() {
            let last = segments.peek().is_none();
            let Some(at) = fields.iter().position(|f| f.name == segment) else {
                if segment == "yaw" && last && within == QUATERNION.name {
                    return Ok(FieldRef { ty: self.this, index, leaf: Leaf::Yaw });
                }
                break;
            };
            index += fields.iter().take(at).map(|f| f.ty.slots()).sum::<usize>();
            let leaf = match fields[at].ty {
                Ty::Struct(m) if last => return Err(self.not_a_leaf(path, m)),
                Ty::Struct(m) => {
                    (within, fields) = (m.name, m.fields);
                    continue;
                }
                Ty::Structs(m) => {
                    let message = format!("is in a sequence of {} messages, and those cannot be mapped", m.name);
                    return Err(FieldError { path: path.to_string(), message, suggestion: None });
                }
                Ty::Prim(p) => Leaf::Prim(p),
                Ty::Text => Leaf::Text,
                Ty::Seq(r) => Leaf::Seq(r),
                Ty::Array(r, n) => Leaf::Array(r, n),
            };
            if last {
                return Ok(FieldRef { ty: self.this, index, leaf });
            }
            break;
        }
        let leaves = self.leaves();
        Err(FieldError {
            path: path.to_string(),
            message: format!("is not a field of {}", self.name),
            suggestion: suggest(path, &leaves),
        })
    }

    fn not_a_leaf(&self, path: &str, m: &MessageType) -> FieldError {
        let under: Vec<String> =
            self.leaves().into_iter().filter(|l| l.strip_prefix(path).is_some_and(|r| r.starts_with('.'))).collect();
        let message = format!("is a {}, not a single value: map one of `{}`", m.name, under.join("`, `"));
        FieldError { path: path.to_string(), message, suggestion: None }
    }

    /// Every path [`field`](Self::field) resolves, in layout order: what a mapping can name,
    /// and what "did you mean" suggestions are drawn from.
    pub fn leaves(&self) -> Vec<String> {
        fn walk(m: &MessageType, prefix: &str, out: &mut Vec<String>) {
            let path = |name: &str| if prefix.is_empty() { name.to_string() } else { format!("{prefix}.{name}") };
            for f in m.fields {
                match f.ty {
                    Ty::Struct(inner) => walk(inner, &path(f.name), out),
                    Ty::Structs(_) => {}
                    _ => out.push(path(f.name)),
                }
            }
            if m.name == QUATERNION.name {
                out.push(path("yaw"));
            }
        }
        let mut out = Vec::new();
        walk(self, "", &mut out);
        out
    }
}

/// The nearest leaf to a mistyped path, if one is near enough to be what was meant.
fn suggest(path: &str, leaves: &[String]) -> Option<String> {
    // The commonest slip is a path missing its outer parts (`position.x` in an Odometry):
    // a single leaf ending in it is surely what was meant.
    let mut tails = leaves.iter().filter(|l| l.strip_suffix(path).is_some_and(|head| head.ends_with('.')));
    if let (Some(only), None) = (tails.next(), tails.next()) {
        return Some(only.clone());
    }
    // Otherwise a typo of one (the mapping file's rule for every "did you mean").
    if path.chars().count() > 256 {
        return None;
    }
    crate::spelling::closest(path, leaves.iter().map(String::as_str)).map(str::to_owned)
}

/// A path that does not name a leaf of a message type.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FieldError {
    /// The path as given.
    pub path: String,
    /// What is wrong, worded to follow the path: "is not a field of nav_msgs/msg/Odometry".
    pub message: String,
    /// The leaf probably meant, when one is close.
    pub suggestion: Option<String>,
}

impl fmt::Display for FieldError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "`{}` {}", self.path, self.message)?;
        match &self.suggestion {
            Some(s) => write!(f, ": did you mean `{s}`?"),
            None => Ok(()),
        }
    }
}

impl std::error::Error for FieldError {}

/// One leaf of one message type, resolved by [`MessageType::field`]: read and written with
/// [`Sample::get`](super::Sample::get) and [`Sample::set`](super::Sample::set).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FieldRef {
    pub(super) ty: &'static MessageType,
    pub(super) index: usize,
    pub(super) leaf: Leaf,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub(super) enum Leaf {
    Prim(Prim),
    Text,
    Seq(Real),
    Array(Real, usize),
    /// Index is the quaternion's `x`; `y`, `z`, `w` follow.
    Yaw,
}

/// What kind of Ayllu value a leaf reads as and accepts.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum FieldKind {
    /// `bool`: a [`Value::Bool`](ayllu_core::Value::Bool).
    Bool,
    /// Any integer width: a [`Value::Int`](ayllu_core::Value::Int) (a `Value::Bool` is accepted as 0 or 1).
    Int,
    /// `float32` or `float64`: a [`Value::Float`](ayllu_core::Value::Float) (a `Value::Int` is accepted).
    Float,
    /// `string`: a [`Value::Text`](ayllu_core::Value::Text).
    Text,
    /// A numeric sequence or fixed-size array: a [`Value::Vector`](ayllu_core::Value::Vector).
    Floats,
    /// The yaw of a quaternion, in radians in (-π, π]: a [`Value::Float`](ayllu_core::Value::Float).
    Yaw,
}

impl FieldRef {
    /// What kind of value the leaf reads as and accepts.
    pub fn kind(&self) -> FieldKind {
        match self.leaf {
            Leaf::Prim(Prim::Bool) => FieldKind::Bool,
            Leaf::Prim(Prim::Real(_)) => FieldKind::Float,
            Leaf::Prim(_) => FieldKind::Int,
            Leaf::Text => FieldKind::Text,
            Leaf::Seq(_) | Leaf::Array(..) => FieldKind::Floats,
            Leaf::Yaw => FieldKind::Yaw,
        }
    }

    /// The leaf's type as a `.msg` file spells it (`"float32[]"`, `"float64[36]"`, `"uint8"`),
    /// for error messages.
    pub fn ros_type(&self) -> String {
        self.leaf.to_string()
    }

    /// The message type the leaf belongs to.
    pub fn message_type(&self) -> &'static MessageType {
        self.ty
    }
}

impl fmt::Display for Leaf {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let real = |r: Real| if r == Real::F32 { "float32" } else { "float64" };
        match *self {
            Leaf::Prim(Prim::Bool) => f.write_str("bool"),
            Leaf::Prim(Prim::U8) => f.write_str("uint8"),
            Leaf::Prim(Prim::I32) => f.write_str("int32"),
            Leaf::Prim(Prim::U32) => f.write_str("uint32"),
            Leaf::Prim(Prim::I64) => f.write_str("int64"),
            Leaf::Prim(Prim::Real(r)) => f.write_str(real(r)),
            Leaf::Text => f.write_str("string"),
            Leaf::Seq(r) => write!(f, "{}[]", real(r)),
            Leaf::Array(r, n) => write!(f, "{}[{n}]", real(r)),
            Leaf::Yaw => f.write_str("yaw (of a quaternion)"),
        }
    }
}
