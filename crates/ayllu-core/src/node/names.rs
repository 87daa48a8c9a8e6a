//! The keys of the node's behavior-name map (`NodeCore::names`): a name of up to
//! [`INLINE`] bytes is kept in the key itself, so that a lookup compares it in the map's own
//! bucket rather than in a string allocated apart.
//!
//! Why: a port message from a connection the node has not heard before is resolved by its
//! behavior's name. In a simulated team every peer of a robot that starts to broadcast does
//! this at once, on a node that is cold by then, and the string behind an `Arc<str>` key was
//! one more cold line for each of them (docs/performance.md, issue 36's receive pass).
//!
//! A key borrows as the `str` it holds and hashes and compares as that `str` does, so the
//! map is looked up by `&str` as before; which form a name takes changes nothing else.

use std::borrow::Borrow;
use std::hash::{Hash, Hasher};
use std::sync::Arc;

/// The longest name kept inline: what fits the 24 bytes an `Arc<str>` key and its tag take.
const INLINE: usize = 22;

/// A behavior name, as a key of `NodeCore::names`.
#[derive(Clone)]
pub(crate) enum NameKey {
    Inline { len: u8, bytes: [u8; INLINE] },
    Shared(Arc<str>),
}

impl NameKey {
    fn as_str(&self) -> &str {
        match self {
            // Copied from a `str` whole (`From<&str>`), so valid UTF-8: the error arm is never
            // taken, and would only make the name compare unequal to every other.
            NameKey::Inline { len, bytes } => std::str::from_utf8(&bytes[..usize::from(*len)]).unwrap_or_default(),
            NameKey::Shared(name) => name,
        }
    }
}

impl From<&str> for NameKey {
    fn from(name: &str) -> NameKey {
        match u8::try_from(name.len()) {
            Ok(len) if name.len() <= INLINE => {
                let mut bytes = [0; INLINE];
                bytes[..name.len()].copy_from_slice(name.as_bytes());
                NameKey::Inline { len, bytes }
            }
            _ => NameKey::Shared(Arc::from(name)),
        }
    }
}

impl Borrow<str> for NameKey {
    fn borrow(&self) -> &str {
        self.as_str()
    }
}

// As the `str` it holds (what `Borrow` asks of a map's key).
impl Hash for NameKey {
    fn hash<H: Hasher>(&self, state: &mut H) {
        self.as_str().hash(state);
    }
}

impl PartialEq for NameKey {
    fn eq(&self, other: &NameKey) -> bool {
        self.as_str() == other.as_str()
    }
}

impl Eq for NameKey {}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    /// Short and long names, ASCII or not, are found by their `str` and only by it.
    #[test]
    fn a_name_is_found_by_its_str_whatever_its_form() {
        let names = ["", "A", "OBS1", "exactly_twenty_two_b_x", "twenty_three_bytes_long", "ñandú", &"x".repeat(300)];
        assert_eq!(names[3].len(), INLINE);
        let map: HashMap<NameKey, usize> = names.iter().enumerate().map(|(i, n)| (NameKey::from(*n), i)).collect();
        for (i, n) in names.iter().enumerate() {
            assert_eq!(map.get(*n), Some(&i), "{n}");
            assert_eq!(NameKey::from(*n).as_str(), *n);
        }
        assert!(matches!(NameKey::from(names[3]), NameKey::Inline { .. }));
        assert!(matches!(NameKey::from(names[4]), NameKey::Shared(_)));
        for other in ["B", "OBS", "OBS10", "twenty_three_bytes_lon", "ñand"] {
            assert_eq!(map.get(other), None, "{other}");
        }
        assert_eq!(std::mem::size_of::<NameKey>(), 24);
    }
}
