//! A scenario's numbers as its data writes them. JSON has no NaN or infinity: a scenario's
//! data spells them as the strings `"NaN"`, `"inf"` and `"-inf"` (the file reader and the
//! Python package write them so), and the scenario's numbers read them back, so that the
//! bounds' check ([`crate::bounds`]), not the parser, refuses them and names their field.
//!
//! Promises: every number field of a scenario (the world's, the radio's, the controllers',
//! the scenario's own) reads through here, so all of them take the same spellings; only the
//! values JSON cannot write are read from strings: `"10"` stays a string, refused.
//!
//! Apart from the bounds because the configurations' own modules read their numbers here,
//! while the bounds read those configurations: one module for both would loop.

use std::fmt;

use serde::de::{self, Deserialize, Deserializer, Unexpected, Visitor};

/// A scenario's number as its data may hold it (module docs).
struct Number(f64);

impl<'de> Deserialize<'de> for Number {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Number, D::Error> {
        struct Any;
        impl Visitor<'_> for Any {
            type Value = Number;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a number (NaN and infinities as \"NaN\", \"inf\", \"-inf\")")
            }
            fn visit_f64<E>(self, v: f64) -> Result<Number, E> {
                Ok(Number(v))
            }
            fn visit_i64<E>(self, v: i64) -> Result<Number, E> {
                Ok(Number(v as f64))
            }
            fn visit_u64<E>(self, v: u64) -> Result<Number, E> {
                Ok(Number(v as f64))
            }
            fn visit_str<E: de::Error>(self, s: &str) -> Result<Number, E> {
                // Only the values JSON cannot write: "10" stays a string, refused as before.
                match s.parse::<f64>() {
                    Ok(v) if !v.is_finite() => Ok(Number(v)),
                    _ => Err(E::invalid_value(Unexpected::Str(s), &self)),
                }
            }
        }
        d.deserialize_any(Any)
    }
}

/// `#[serde(deserialize_with)]` of a scenario's `f64` fields (module docs).
pub(crate) fn number_de<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Number::deserialize(d).map(|n| n.0)
}

/// [`number_de`] for an optional number.
pub(crate) fn optional_number_de<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    Option::<Number>::deserialize(d).map(|n| n.map(|n| n.0))
}

/// [`number_de`] for a pair (an arena, a place).
pub(crate) fn pair_de<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 2], D::Error> {
    <[Number; 2]>::deserialize(d).map(|[a, b]| [a.0, b.0])
}

/// [`number_de`] for an optional pair.
pub(crate) fn optional_pair_de<'de, D: Deserializer<'de>>(d: D) -> Result<Option<[f64; 2]>, D::Error> {
    Option::<[Number; 2]>::deserialize(d).map(|p| p.map(|[a, b]| [a.0, b.0]))
}

/// A non-finite number as a scenario's data spells it (module docs): `"NaN"`, `"inf"`,
/// `"-inf"`. The file reader uses it for TOML's `nan` and `inf`.
pub fn non_finite_text(v: f64) -> &'static str {
    if v.is_nan() {
        "NaN"
    } else if v > 0.0 {
        "inf"
    } else {
        "-inf"
    }
}
