//! Admission of unproven newcomers to the peer table (docs/semantics.md N4, "Who keeps a place
//! in the peer table"; docs/security.md).
//!
//! In an open team anyone can write any sender id and, on a shared network, any source
//! address: a new id costs a forger nothing. What a forger cannot multiply for free is source
//! addresses that the network delivers, so newcomers that have not proven their address are
//! let in at a bounded rate per source address and per address block (an IPv4 /24, an IPv6
//! /48), each a token bucket. A newcomer refused here is dropped and counted; it is let in at
//! a later datagram, or at once if it proves its address (an ECHO of our cookie).
//!
//! Promises: deterministic (time is the node's [`Instant`], given by the caller); memory
//! bounded ([`MAX_TRACKED`] buckets of each kind; when full, the bucket idle longest is
//! forgotten, which can only let its address in sooner, never starve another); nothing here
//! allocates once the maps are full.

use std::collections::BTreeMap;
use std::net::IpAddr;

use ayllu_core::{Duration, Instant};

/// Buckets kept of each kind (addresses, blocks).
pub(crate) const MAX_TRACKED: usize = 4096;

/// A token bucket: `burst` tokens at most, one more every `every`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Bucket {
    tokens: u32,
    /// When the tokens were last counted.
    pub(crate) at: Instant,
}

/// A rate: `burst` at once, then one every `every`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Rate {
    pub(crate) burst: u32,
    pub(crate) every: Duration,
}

impl Rate {
    /// A bucket of this rate, full at `now`.
    pub(crate) fn full(self, now: Instant) -> Bucket {
        Bucket { tokens: self.burst, at: now }
    }

    /// Refill `b` to `now`.
    fn refill(self, b: &mut Bucket, now: Instant) {
        if now <= b.at || self.every.as_nanos() == 0 {
            return;
        }
        let gained = (now - b.at).as_nanos() / self.every.as_nanos();
        if gained == 0 {
            return;
        }
        b.tokens = u32::try_from(u64::from(b.tokens) + gained).unwrap_or(u32::MAX).min(self.burst);
        // Keep the remainder: a rate of 1 per 250 ms stays that rate when asked every 100 ms.
        b.at = if b.tokens == self.burst { now } else { b.at + self.every * gained };
    }

    /// Whether `b` holds a token at `now` (none is taken).
    pub(crate) fn peek(self, b: &mut Bucket, now: Instant) -> bool {
        self.refill(b, now);
        b.tokens > 0
    }

    /// Take one token from `b` at `now`, if there is one.
    pub(crate) fn take(self, b: &mut Bucket, now: Instant) -> bool {
        self.refill(b, now);
        if b.tokens == 0 {
            return false;
        }
        b.tokens -= 1;
        true
    }
}

/// Per source address: a robot greets once a period; a burst covers a restart's churn.
pub(crate) const PER_ADDRESS: Rate = Rate { burst: 8, every: Duration::from_millis(250) };
/// Per address block: a team starting together in one subnet (64 at once), then 16 a second.
pub(crate) const PER_BLOCK: Rate = Rate { burst: 64, every: Duration::from_millis(62) };

/// The block an address belongs to: its /24 (IPv4) or /48 (IPv6); an IPv4-mapped IPv6 address
/// counts as IPv4, so one host cannot look like two blocks.
pub(crate) fn block(ip: IpAddr) -> IpAddr {
    match ip {
        IpAddr::V4(v4) => {
            let [a, b, c, _] = v4.octets();
            IpAddr::from([a, b, c, 0])
        }
        IpAddr::V6(v6) => match v6.to_ipv4_mapped() {
            Some(v4) => block(IpAddr::V4(v4)),
            None => {
                let s = v6.segments();
                IpAddr::from([s[0], s[1], s[2], 0, 0, 0, 0, 0])
            }
        },
    }
}

/// Token buckets by source address and by block.
#[derive(Default)]
pub(crate) struct Admission {
    addresses: BTreeMap<IpAddr, Bucket>,
    blocks: BTreeMap<IpAddr, Bucket>,
}

impl Admission {
    /// Whether a newcomer from `ip` may be let in now: a token from its address's bucket and
    /// one from its block's, both or neither taken.
    pub(crate) fn admit(&mut self, now: Instant, ip: IpAddr) -> bool {
        let blk = block(ip);
        let a = bucket(&mut self.addresses, ip, PER_ADDRESS, now);
        if !PER_ADDRESS.peek(a, now) {
            return false;
        }
        let b = bucket(&mut self.blocks, blk, PER_BLOCK, now);
        if !PER_BLOCK.take(b, now) {
            return false;
        }
        let a = self.addresses.get_mut(&ip).expect("made above");
        a.tokens -= 1;
        true
    }
}

/// `map`'s bucket for `key`, made full if new; when the map is full, the bucket counted longest
/// ago goes first (it has refilled the most: forgetting it only lets its key in sooner).
fn bucket(map: &mut BTreeMap<IpAddr, Bucket>, key: IpAddr, rate: Rate, now: Instant) -> &mut Bucket {
    if !map.contains_key(&key) && map.len() >= MAX_TRACKED {
        if let Some(oldest) = map.iter().min_by_key(|(_, b)| b.at).map(|(k, _)| *k) {
            map.remove(&oldest);
        }
    }
    map.entry(key).or_insert_with(|| rate.full(now))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(n: u64) -> Instant {
        Instant::ZERO + Duration::from_millis(n)
    }

    #[test]
    fn an_address_gets_its_burst_then_its_rate() {
        let mut a = Admission::default();
        let ip: IpAddr = "10.0.0.5".parse().unwrap();
        let let_in = (0..100).filter(|_| a.admit(ms(0), ip)).count();
        assert_eq!(let_in, PER_ADDRESS.burst as usize);
        assert!(!a.admit(ms(100), ip));
        assert!(a.admit(ms(250), ip), "one more after a period");
        assert!(!a.admit(ms(260), ip));
        let let_in = (0..100).filter(|_| a.admit(ms(10_000), ip)).count();
        assert_eq!(let_in, PER_ADDRESS.burst as usize, "refilled to the burst, no more");
    }

    #[test]
    fn many_addresses_in_one_block_share_the_blocks_rate() {
        let mut a = Admission::default();
        let mut let_in = 0;
        for host in 1..=200u8 {
            for _ in 0..4 {
                let_in += usize::from(a.admit(ms(0), IpAddr::from([10, 0, 0, host])));
            }
        }
        assert_eq!(let_in, PER_BLOCK.burst as usize);
        assert!(a.admit(ms(0), "10.0.1.1".parse().unwrap()), "another block has its own");
        assert_eq!(block("::ffff:10.0.0.7".parse().unwrap()), block("10.0.0.9".parse().unwrap()));
        assert_eq!(block("2001:db8:1:2::1".parse().unwrap()), block("2001:db8:1:ffff::9".parse().unwrap()));
    }

    #[test]
    fn memory_stays_bounded() {
        let mut a = Admission::default();
        for i in 0..(MAX_TRACKED as u32 + 500) {
            a.admit(ms(u64::from(i)), IpAddr::from(i.to_be_bytes()));
        }
        assert!(a.addresses.len() <= MAX_TRACKED && a.blocks.len() <= MAX_TRACKED);
    }
}
