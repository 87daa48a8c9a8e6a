//! A sample's bytes: CDR decoding ([`Decode`], the seed for ros2-client's
//! `Subscription::take_seed`) and encoding ([`Encoded`], what a `Publisher<Encoded>`
//! publishes), through the very serde (de)serializer RustDDS uses for a topic's samples.
//!
//! Promises (the byte ones of [`crate::messages`]): byte-exact with ROS 2's plain CDR; no
//! panic on any input, the cause of a failed decode left in the caller's cell; a sequence
//! longer than [`Decode::max_elements`] refused from its length alone, before anything is
//! allocated for it.

use std::cell::Cell;
use std::fmt;
use std::marker::PhantomData;
use std::sync::Arc;

use serde::de::{self, DeserializeSeed, Deserializer, SeqAccess, Visitor};
use serde::ser::{self, Serialize, SerializeSeq, SerializeTuple, Serializer};

use super::sample::{Sample, Slot};
use super::schema::{MessageType, Prim, Real, Ty};

impl MessageType {
    /// How many items the decoder reads for one of these: one per field, plus one for the
    /// length of each sequence (see [`Fields`]).
    fn items(&self) -> usize {
        self.fields.iter().map(|f| if matches!(f.ty, Ty::Seq(_) | Ty::Structs(_)) { 2 } else { 1 }).sum()
    }
}

/// Why a payload could not be decoded, left in [`Decode::cause`].
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum DecodeCause {
    /// The payload ended before the message did.
    Truncated,
    /// A sequence longer than [`Decode::max_elements`], refused from its length field.
    TooLong,
    /// A string that is not UTF-8.
    BadText,
    /// Anything else: a bool neither 0 nor 1, a string without its NUL terminator.
    Malformed,
}

impl DecodeCause {
    /// The cause's name for counters and logs (`too_long`).
    pub fn name(self) -> &'static str {
        match self {
            DecodeCause::Truncated => "truncated",
            DecodeCause::TooLong => "too_long",
            DecodeCause::BadText => "bad_text",
            DecodeCause::Malformed => "malformed",
        }
    }
}

impl fmt::Display for DecodeCause {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Decodes one sample of `ty` from the CDR deserializer RustDDS hands it: the seed for
/// `Subscription::<Sample>::take_seed`.
///
/// On failure the cause is left in `cause`. Reset it before each take: a payload in an
/// encoding RustDDS does not decode never reaches the seed, and fails with the cell untouched.
#[derive(Copy, Clone, Debug)]
pub struct Decode<'a> {
    /// The type the topic carries.
    pub ty: &'static MessageType,
    /// The most elements a sequence may have; a longer one is refused (`TooLong`) from its
    /// length field, before anything is allocated for it.
    pub max_elements: usize,
    /// Where the cause of a failed decode is left.
    pub cause: &'a Cell<Option<DecodeCause>>,
}

/// A lying length must not make a large allocation before the payload runs out: vectors
/// start at most this big and grow as elements actually arrive.
const PREALLOCATE: usize = 4096;

impl Decode<'_> {
    fn fail<E: de::Error>(&self, cause: DecodeCause, message: impl fmt::Display) -> E {
        self.cause.set(Some(cause));
        E::custom(message)
    }
}

impl<'de> DeserializeSeed<'de> for Decode<'_> {
    type Value = Sample;

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Sample, D::Error> {
        self.cause.set(None);
        let mut slots = Vec::with_capacity(self.ty.slots());
        let read = Fields { ty: self.ty, ctx: self, out: &mut slots }.deserialize(d);
        if read.is_err() && self.cause.get().is_none() {
            self.cause.set(Some(DecodeCause::Malformed));
        }
        read.map(|()| Sample { ty: self.ty, slots })
    }
}

/// The next item of a tuple. Every error this module raises records its cause first, so an
/// error without one came from the CDR deserializer itself, whose reads of numbers, lengths
/// and byte runs fail only when the payload runs out.
fn next<'de, A: SeqAccess<'de>, S: DeserializeSeed<'de>>(
    seq: &mut A,
    ctx: Decode<'_>,
    seed: S,
) -> Result<S::Value, A::Error> {
    match seq.next_element_seed(seed) {
        Ok(Some(v)) => Ok(v),
        Ok(None) => Err(ctx.fail(DecodeCause::Malformed, "the deserializer ended a tuple early")),
        Err(e) => {
            if ctx.cause.get().is_none() {
                ctx.cause.set(Some(DecodeCause::Truncated));
            }
            Err(e)
        }
    }
}

/// A sequence's length, refused if over the limit.
///
/// CDR's `deserialize_seq` reads the length itself and hides it (its `SeqAccess` gives no
/// `size_hint`), so it is read here as the `uint32` it is, and the elements as a tuple of that
/// length: the same bytes, but the length is known before the first element.
fn length<'de, A: SeqAccess<'de>>(seq: &mut A, ctx: Decode<'_>) -> Result<usize, A::Error> {
    let len = next(seq, ctx, PhantomData::<u32>)?;
    match usize::try_from(len) {
        Ok(n) if n <= ctx.max_elements => Ok(n),
        _ => Err(ctx.fail(DecodeCause::TooLong, format_args!("a sequence of {len}, over {}", ctx.max_elements))),
    }
}

/// Reads one message's fields, appending their slots.
struct Fields<'s, 'a> {
    ty: &'static MessageType,
    ctx: Decode<'a>,
    out: &'s mut Vec<Slot>,
}

impl<'de> DeserializeSeed<'de> for Fields<'_, '_> {
    type Value = ();

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        // A CDR struct is its fields back to back, exactly what a tuple is.
        d.deserialize_tuple(self.ty.items(), self)
    }
}

impl<'de> Visitor<'de> for Fields<'_, '_> {
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "a {}", self.ty.name)
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        let Fields { ty, ctx, out } = self;
        for f in ty.fields {
            let slot = match f.ty {
                Ty::Struct(m) => {
                    next(&mut seq, ctx, Fields { ty: m, ctx, out: &mut *out })?;
                    continue;
                }
                Ty::Prim(p) => next(&mut seq, ctx, PrimSeed(p, ctx))?,
                Ty::Text => next(&mut seq, ctx, TextSeed(ctx))?,
                Ty::Array(real, len) => Slot::Floats(next(&mut seq, ctx, Reals { real, len, ctx })?),
                Ty::Seq(real) => {
                    let len = length(&mut seq, ctx)?;
                    Slot::Floats(next(&mut seq, ctx, Reals { real, len, ctx })?)
                }
                Ty::Structs(m) => {
                    let len = length(&mut seq, ctx)?;
                    Slot::Records(next(&mut seq, ctx, Records { ty: m, len, ctx })?)
                }
            };
            out.push(slot);
        }
        Ok(())
    }
}

struct PrimSeed<'a>(Prim, Decode<'a>);

impl<'de> DeserializeSeed<'de> for PrimSeed<'_> {
    type Value = Slot;

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Slot, D::Error> {
        use serde::Deserialize;
        Ok(match self.0 {
            // Read as the byte it is, so a bad value is told apart from a short payload.
            Prim::Bool => match u8::deserialize(d)? {
                0 => Slot::Bool(false),
                1 => Slot::Bool(true),
                b => return Err(self.1.fail(DecodeCause::Malformed, format_args!("{b} is not a bool"))),
            },
            Prim::U8 => Slot::Int(u8::deserialize(d)?.into()),
            Prim::I32 => Slot::Int(i32::deserialize(d)?.into()),
            Prim::U32 => Slot::Int(u32::deserialize(d)?.into()),
            Prim::I64 => Slot::Int(i64::deserialize(d)?),
            Prim::Real(Real::F32) => Slot::Float(f32::deserialize(d)?.into()),
            Prim::Real(Real::F64) => Slot::Float(f64::deserialize(d)?),
        })
    }
}

struct TextSeed<'a>(Decode<'a>);

impl<'de> DeserializeSeed<'de> for TextSeed<'_> {
    type Value = Slot;

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Slot, D::Error> {
        // A CDR string is a byte run whose length counts the NUL: read as bytes, so that
        // invalid UTF-8 is told apart from a short payload.
        d.deserialize_bytes(self)
    }
}

impl<'de> Visitor<'de> for TextSeed<'_> {
    type Value = Slot;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a string")
    }

    fn visit_bytes<E: de::Error>(self, bytes: &[u8]) -> Result<Slot, E> {
        let text = match bytes.split_last() {
            // Length 0 is not valid CDR but some DDSs send it for "": RustDDS accepts it too.
            None => bytes,
            Some((0, text)) => text,
            Some(_) => return Err(self.0.fail(DecodeCause::Malformed, "a string without its NUL")),
        };
        match std::str::from_utf8(text) {
            Ok(s) => Ok(Slot::Text(Arc::from(s))),
            Err(_) => Err(self.0.fail(DecodeCause::BadText, "a string that is not UTF-8")),
        }
    }
}

/// `len` floats, back to back (the length, if any, already read).
struct Reals<'a> {
    real: Real,
    len: usize,
    ctx: Decode<'a>,
}

impl<'de> DeserializeSeed<'de> for Reals<'_> {
    type Value = Arc<[f64]>;

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Arc<[f64]>, D::Error> {
        d.deserialize_tuple(self.len, self)
    }
}

impl<'de> Visitor<'de> for Reals<'_> {
    type Value = Arc<[f64]>;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} floats", self.len)
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Arc<[f64]>, A::Error> {
        let mut xs = Vec::with_capacity(self.len.min(PREALLOCATE));
        for _ in 0..self.len {
            xs.push(match self.real {
                Real::F32 => f64::from(next(&mut seq, self.ctx, PhantomData::<f32>)?),
                Real::F64 => next(&mut seq, self.ctx, PhantomData::<f64>)?,
            });
        }
        Ok(Arc::from(xs))
    }
}

/// `len` messages of type `ty`, back to back.
struct Records<'a> {
    ty: &'static MessageType,
    len: usize,
    ctx: Decode<'a>,
}

impl<'de> DeserializeSeed<'de> for Records<'_> {
    type Value = Vec<Vec<Slot>>;

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
        d.deserialize_tuple(self.len, self)
    }
}

impl<'de> Visitor<'de> for Records<'_> {
    type Value = Vec<Vec<Slot>>;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {}", self.len, self.ty.name)
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
        let mut records = Vec::with_capacity(self.len.min(PREALLOCATE));
        for _ in 0..self.len {
            let mut record = Vec::with_capacity(self.ty.slots());
            next(&mut seq, self.ctx, Fields { ty: self.ty, ctx: self.ctx, out: &mut record })?;
            records.push(record);
        }
        Ok(records)
    }
}

/// A sample to publish: serializes as its type's CDR, for `Publisher<Encoded>::publish`.
#[derive(Clone, Debug, PartialEq)]
pub struct Encoded(pub Sample);

impl From<Sample> for Encoded {
    fn from(sample: Sample) -> Encoded {
        Encoded(sample)
    }
}

impl Serialize for Encoded {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        Item { ty: Ty::Struct(self.0.ty), slots: &self.0.slots }.serialize(s)
    }
}

/// One field (or a whole message) and its slots.
struct Item<'s> {
    ty: Ty,
    slots: &'s [Slot],
}

impl Serialize for Item<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        // A Sample's slots always match its type (they are only made by default_sample,
        // Decode and set), so the errors below are never raised; they keep a bug from
        // becoming a panic or a wrong message.
        let mismatch = || ser::Error::custom("the sample does not match its message type");
        let too_long = || ser::Error::custom("over 2^32 - 1 elements, more than CDR can say");
        match (self.ty, self.slots) {
            (Ty::Struct(m), slots) => {
                let mut tuple = s.serialize_tuple(m.fields.len())?;
                let mut rest = slots;
                for f in m.fields {
                    let (here, tail) = rest.split_at_checked(f.ty.slots()).ok_or_else(mismatch)?;
                    tuple.serialize_element(&Item { ty: f.ty, slots: here })?;
                    rest = tail;
                }
                if !rest.is_empty() {
                    return Err(mismatch());
                }
                tuple.end()
            }
            (Ty::Prim(Prim::Bool), [Slot::Bool(b)]) => s.serialize_bool(*b),
            (Ty::Prim(Prim::U8), [Slot::Int(i)]) => s.serialize_u8(u8::try_from(*i).map_err(|_| mismatch())?),
            (Ty::Prim(Prim::I32), [Slot::Int(i)]) => s.serialize_i32(i32::try_from(*i).map_err(|_| mismatch())?),
            (Ty::Prim(Prim::U32), [Slot::Int(i)]) => s.serialize_u32(u32::try_from(*i).map_err(|_| mismatch())?),
            (Ty::Prim(Prim::I64), [Slot::Int(i)]) => s.serialize_i64(*i),
            (Ty::Prim(Prim::Real(Real::F32)), [Slot::Float(x)]) => s.serialize_f32(*x as f32),
            (Ty::Prim(Prim::Real(Real::F64)), [Slot::Float(x)]) => s.serialize_f64(*x),
            // The length written counts the NUL, so one less than u32::MAX is the most.
            (Ty::Text, [Slot::Text(t)]) if t.len() < u32::MAX as usize => s.serialize_str(t),
            (Ty::Text, [Slot::Text(_)]) => Err(too_long()),
            (Ty::Seq(real), [Slot::Floats(xs)]) => {
                let len = u32::try_from(xs.len()).map_err(|_| too_long())?;
                let mut seq = s.serialize_seq(Some(len as usize))?;
                for x in xs.iter() {
                    match real {
                        Real::F32 => seq.serialize_element(&(*x as f32))?,
                        Real::F64 => seq.serialize_element(x)?,
                    }
                }
                seq.end()
            }
            (Ty::Array(real, n), [Slot::Floats(xs)]) if xs.len() == n => {
                let mut tuple = s.serialize_tuple(n)?;
                for x in xs.iter() {
                    match real {
                        Real::F32 => tuple.serialize_element(&(*x as f32))?,
                        Real::F64 => tuple.serialize_element(x)?,
                    }
                }
                tuple.end()
            }
            (Ty::Structs(m), [Slot::Records(records)]) => {
                let len = u32::try_from(records.len()).map_err(|_| too_long())?;
                let mut seq = s.serialize_seq(Some(len as usize))?;
                for record in records {
                    seq.serialize_element(&Item { ty: Ty::Struct(m), slots: record })?;
                }
                seq.end()
            }
            _ => Err(mismatch()),
        }
    }
}
