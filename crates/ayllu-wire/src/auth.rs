//! Authentication (N5): the datagram MAC and the per-sender replay window.
//!
//! The MAC is HMAC-SHA256 under the 32-byte team key over every byte before it, truncated to
//! its first 16 bytes, and compared in constant time so that a forger learns nothing from how
//! long a refusal takes. [`ReplayWindow`] remembers which sequence numbers a sender's
//! authenticated datagrams used; the runtime consults it only *after* the MAC checked out, so
//! forged datagrams can never move it.

use hmac::{Hmac, Mac};
use sha2::Sha256;

use crate::{KEY_LEN, MAC_LEN};

/// A team key.
pub type Key = [u8; KEY_LEN];

type HmacSha256 = Hmac<Sha256>;

fn keyed(key: &Key) -> HmacSha256 {
    // HMAC takes keys of any length; this cannot fail for 32 bytes.
    match HmacSha256::new_from_slice(key) {
        Ok(m) => m,
        Err(_) => unreachable!("HMAC accepts keys of every length"),
    }
}

/// The MAC of `data` under `key`: HMAC-SHA256 truncated to 16 bytes.
pub fn mac(key: &Key, data: &[u8]) -> [u8; MAC_LEN] {
    let mut m = keyed(key);
    m.update(data);
    let full = m.finalize().into_bytes();
    let mut tag = [0u8; MAC_LEN];
    tag.copy_from_slice(&full[..MAC_LEN]);
    tag
}

/// Whether `tag` is the MAC of `data` under `key`, compared in constant time.
pub fn verify_mac(key: &Key, data: &[u8], tag: &[u8]) -> bool {
    if tag.len() != MAC_LEN {
        return false;
    }
    let mut m = keyed(key);
    m.update(data);
    m.verify_truncated_left(tag).is_ok()
}

/// A key written as 64 hex digits (either case), as tools accept it; `None` otherwise.
pub fn parse_key_hex(hex: &str) -> Option<Key> {
    let hex = hex.as_bytes();
    if hex.len() != 2 * KEY_LEN {
        return None;
    }
    let digit = |c: u8| (c as char).to_digit(16).map(|d| d as u8);
    let mut key = [0u8; KEY_LEN];
    for (k, pair) in key.iter_mut().zip(hex.chunks_exact(2)) {
        *k = digit(pair[0])? << 4 | digit(pair[1])?;
    }
    Some(key)
}

/// The sequence numbers already accepted from one sender: the newest, and a bitmap of the 64
/// numbers just below it (bit `i` set: `newest - 1 - i` was accepted).
///
/// A number is accepted once, and only if it is newer than the newest or within the 64 below
/// it and not yet seen; anything further back is refused, since the window can no longer
/// tell whether it was seen. Senders number datagrams strictly increasingly, so an honest
/// datagram is refused only if it arrives more than 64 datagrams late.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq)]
pub struct ReplayWindow {
    /// `None` until the first datagram is accepted.
    newest: Option<u64>,
    seen: u64,
}

impl ReplayWindow {
    /// A window that has accepted nothing yet.
    pub const fn new() -> Self {
        ReplayWindow { newest: None, seen: 0 }
    }

    /// A window restored from a saved high-water mark (a restart): everything up to and
    /// including `newest` counts as seen, so only newer numbers are accepted.
    pub const fn after(newest: u64) -> Self {
        ReplayWindow { newest: Some(newest), seen: u64::MAX }
    }

    /// The newest sequence number accepted so far.
    pub fn newest(&self) -> Option<u64> {
        self.newest
    }

    /// Whether `seq` would be accepted now (without recording it).
    pub fn is_fresh(&self, seq: u64) -> bool {
        let Some(newest) = self.newest else { return true };
        if seq > newest {
            return true;
        }
        let back = newest - seq;
        (1..=64).contains(&back) && self.seen & (1u64 << (back - 1)) == 0
    }

    /// Accept `seq` if it is fresh and record it; `false` means the datagram is `replayed`
    /// and must be dropped. Call only for datagrams whose MAC was verified.
    pub fn accept(&mut self, seq: u64) -> bool {
        if !self.is_fresh(seq) {
            return false;
        }
        match self.newest {
            Some(newest) if seq < newest => self.seen |= 1u64 << (newest - seq - 1),
            Some(newest) => {
                // seq > newest: slide the window up; the old newest lands at bit `shift - 1`.
                let shift = seq - newest;
                self.seen = if shift > 64 {
                    0
                } else if shift == 64 {
                    1 << 63
                } else {
                    (self.seen << shift) | (1 << (shift - 1))
                };
                self.newest = Some(seq);
            }
            None => {
                self.newest = Some(seq);
                self.seen = 0;
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rfc4231_case_2_truncated() {
        // RFC 4231 test case 2 uses a 4-byte key; ours are 32 bytes, so check the HMAC itself
        // through a key padded with zeros, which HMAC treats identically (keys shorter than the
        // block are zero-padded).
        let mut key = [0u8; 32];
        key[..4].copy_from_slice(b"Jefe");
        let tag = mac(&key, b"what do ya want for nothing?");
        assert_eq!(
            tag,
            [0x5b, 0xdc, 0xc1, 0x46, 0xbf, 0x60, 0x75, 0x4e, 0x6a, 0x04, 0x24, 0x26, 0x08, 0x95, 0x75, 0xc7]
        );
        assert!(verify_mac(&key, b"what do ya want for nothing?", &tag));
        assert!(!verify_mac(&key, b"what do ya want for nothing!", &tag));
        assert!(!verify_mac(&key, b"what do ya want for nothing?", &tag[..15]));
    }

    #[test]
    fn key_hex() {
        let k = parse_key_hex(&"0aF1".repeat(16)).unwrap();
        assert_eq!(&k[..2], &[0x0a, 0xf1]);
        assert!(parse_key_hex(&"0".repeat(63)).is_none());
        assert!(parse_key_hex(&format!("{}g", "0".repeat(63))).is_none());
        assert!(parse_key_hex(&"é".repeat(32)).is_none());
    }

    #[test]
    fn replay_window() {
        let mut w = ReplayWindow::new();
        assert!(w.accept(100));
        assert!(!w.accept(100), "exact repeat");
        assert!(w.accept(99), "late but inside the window");
        assert!(!w.accept(99));
        assert!(w.accept(36), "64 below the newest is the window's last slot");
        assert!(!w.accept(35), "65 below: too old to tell");
        assert!(w.accept(164));
        assert!(w.is_fresh(101) && !w.is_fresh(100) && !w.is_fresh(99), "old newest kept at bit 63");
        assert!(w.accept(1000));
        assert!(w.is_fresh(999) && !w.is_fresh(164) && !w.is_fresh(1000));
        assert!(w.accept(u64::MAX));
        assert!(!w.accept(u64::MAX));
        assert_eq!(w.newest(), Some(u64::MAX));
    }
}
