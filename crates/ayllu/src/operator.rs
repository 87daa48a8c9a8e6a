//! The operator gate: a node given an operator public key applies structure changes
//! (CONNECT, DISCONNECT) only when its operator signed them, and each signed request once
//! (spec/protocol.md, "Operator signature"; docs/security.md).
//!
//! The signature itself is checked by `ayllu_wire::operator`; this module adds freshness. A
//! captured signed request could otherwise be sent again later — after the receiver forgot it
//! answered it, or after the receiver restarted — and rewire the node a second time. So the
//! gate keeps, per requester, a replay window of the signed request ids it applied (the same
//! window datagrams use, N5), outliving peer entries and, with `state=PATH`, restarts. A repeat
//! of an id applied in the last [`RETRY_HORIZON`] is a retry (N2) and goes through, to be
//! answered from memory by the core.
//!
//! A signature costs tens of microseconds to verify, and anyone can send a forged one: before a
//! signature is verified, its requester must be within a rate (the core's default request rate,
//! 50 a second, 100 at once) and all requesters together within 1,000 a second (bursts of
//! 200); beyond them the request is dropped unanswered, unverified (`signature_rate_limited`),
//! and the requester retries (N2). A flood of forged signatures so costs at most that many verifications a
//! second, whatever ids it writes.
//!
//! Promises: memory is bounded (4096 requesters' windows and rate buckets, 1024 retries
//! remembered); a request that was refused moves no window.

use std::collections::{BTreeMap, VecDeque};

use ayllu_core::{Duration, Instant, NodeId};
use ayllu_wire::{OperatorPublic, OperatorSignature, ReplayWindow, SignedRequest};

use crate::admission::{Bucket, Rate};

/// Signatures verified per requester: the core's default request rate (`Limits`).
const VERIFY_EACH: Rate = Rate { burst: 100, every: Duration::from_millis(20) };
/// Signatures verified over all requesters together: about 5 % of a core at ~50 us each.
const VERIFY_ALL: Rate = Rate { burst: 200, every: Duration::from_millis(1) };

/// Requesters whose signed-request windows are kept (the least recently used is forgotten
/// first: it can then replay requests older than its newest applied one).
pub(crate) const MAX_REQUESTERS: usize = 4096;
/// Signed requests remembered as retry-able.
const MAX_RECENT: usize = 1024;
/// How long after applying a signed request its repeats are taken for retries (requesters
/// retry every 200 ms, 25 times: 5 s).
pub const RETRY_HORIZON: Duration = Duration::from_secs(10);

/// Why a structure change was refused.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub(crate) enum Refusal {
    /// No signature, and this node requires one.
    Unsigned,
    /// A signature that does not verify under the operator key.
    BadSignature,
    /// A valid signature on a request applied before (outside the retry horizon).
    Replayed,
    /// Over the rate of signatures verified (not verified, not answered).
    RateLimited,
}

impl Refusal {
    /// The counter name.
    pub(crate) fn cause(self) -> &'static str {
        match self {
            Refusal::Unsigned => "unsigned",
            Refusal::BadSignature => "bad_signature",
            Refusal::Replayed => "replayed",
            Refusal::RateLimited => "signature_rate_limited",
        }
    }
}

/// The operator key and what it has let through.
pub(crate) struct OperatorGate {
    key: OperatorPublic,
    windows: BTreeMap<NodeId, (ReplayWindow, Instant)>,
    recent: VecDeque<(NodeId, u64, Instant)>,
    /// Signatures left to verify, per requester and in all.
    rates: BTreeMap<NodeId, Bucket>,
    all: Option<Bucket>,
    /// Windows changed since the state file was last written.
    pub(crate) dirty: bool,
}

impl OperatorGate {
    pub(crate) fn new(key: OperatorPublic, windows: BTreeMap<NodeId, ReplayWindow>) -> Self {
        let windows = windows.into_iter().map(|(n, w)| (n, (w, Instant::ZERO))).collect();
        OperatorGate { key, windows, recent: VecDeque::new(), rates: BTreeMap::new(), all: None, dirty: false }
    }

    /// Whether `request` may be applied. Only structure changes are gated; other requests
    /// always may.
    pub(crate) fn admit(
        &mut self,
        now: Instant,
        request: &SignedRequest<'_>,
        signature: Option<&OperatorSignature>,
    ) -> Result<(), Refusal> {
        if !ayllu_wire::operator::changes_structure(request.body) {
            return Ok(());
        }
        let sig = signature.ok_or(Refusal::Unsigned)?;
        if !self.may_verify(now, request.requester) {
            return Err(Refusal::RateLimited);
        }
        if !self.key.verify(request, sig) {
            return Err(Refusal::BadSignature);
        }
        let (requester, id) = (request.requester, request.id);
        while self.recent.front().is_some_and(|(_, _, at)| *at + RETRY_HORIZON <= now) {
            self.recent.pop_front();
        }
        if self.recent.iter().any(|(n, i, _)| *n == requester && *i == id) {
            return Ok(());
        }
        if !self.windows.contains_key(&requester) && self.windows.len() >= MAX_REQUESTERS {
            if let Some(oldest) = self.windows.iter().min_by_key(|(_, (_, used))| *used).map(|(n, _)| *n) {
                self.windows.remove(&oldest);
            }
        }
        let (window, used) = self.windows.entry(requester).or_insert_with(|| (ReplayWindow::new(), now));
        if !window.accept(id) {
            return Err(Refusal::Replayed);
        }
        *used = now;
        self.dirty = true;
        if self.recent.len() >= MAX_RECENT {
            self.recent.pop_front();
        }
        self.recent.push_back((requester, id, now));
        Ok(())
    }

    /// Whether one more signature from `requester` may be verified now (its rate, then the
    /// rate of all; a token is taken from both or neither).
    fn may_verify(&mut self, now: Instant, requester: NodeId) -> bool {
        if !self.rates.contains_key(&requester) && self.rates.len() >= MAX_REQUESTERS {
            // The bucket counted longest ago has refilled the most: forgetting it only lets its
            // requester verify sooner.
            if let Some(oldest) = self.rates.iter().min_by_key(|(_, b)| b.at).map(|(n, _)| *n) {
                self.rates.remove(&oldest);
            }
        }
        let each = self.rates.entry(requester).or_insert_with(|| VERIFY_EACH.full(now));
        if !VERIFY_EACH.peek(each, now) {
            return false;
        }
        let all = self.all.get_or_insert_with(|| VERIFY_ALL.full(now));
        if !VERIFY_ALL.take(all, now) {
            return false;
        }
        self.rates.get_mut(&requester).is_some_and(|b| VERIFY_EACH.take(b, now))
    }

    /// The newest signed request id applied from each requester, to save.
    pub(crate) fn marks(&self) -> impl Iterator<Item = (NodeId, u64)> + '_ {
        self.windows.iter().filter_map(|(n, (w, _))| w.newest().map(|id| (*n, id)))
    }
}

/// Make an operator key pair: the secret is written to a new file `path` (64 hex digits,
/// readable by its owner only; an existing file is never overwritten) and the public key,
/// which robots are given (`operator=` in their URL), is returned.
pub fn keygen(path: &std::path::Path) -> Result<OperatorPublic, crate::error::Error> {
    use std::io::Write as _;
    let io = |what: String| move |e: std::io::Error| crate::error::Error::Io { what, error: e.to_string() };
    let mut seed = [0u8; 32];
    getrandom::getrandom(&mut seed).map_err(|e| crate::error::Error::Io {
        what: "drawing an operator secret from the operating system".into(),
        error: e.to_string(),
    })?;
    let secret = ayllu_wire::OperatorSecret::from_seed(&seed);
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create_new(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
    let mut file = options.open(path).map_err(io(format!("creating the operator secret file {}", path.display())))?;
    let hex: String = seed.iter().map(|b| format!("{b:02x}")).collect();
    writeln!(file, "{hex}").map_err(io(format!("writing {}", path.display())))?;
    Ok(secret.public())
}

#[cfg(test)]
mod tests {
    use super::*;
    use ayllu_core::{ConnectionId, ControlBody};
    use ayllu_wire::OperatorSecret;

    fn t(ms: u64) -> Instant {
        Instant::ZERO + Duration::from_millis(ms)
    }

    #[test]
    fn only_signed_structure_changes_pass_once() {
        let secret = OperatorSecret::from_seed(&[3; 32]);
        let mut gate = OperatorGate::new(secret.public(), BTreeMap::new());
        let body = ControlBody::Disconnect { conn: ConnectionId(1) };
        let req = |requester, id, body| SignedRequest {
            team: 0,
            requester: NodeId(requester),
            receiver: NodeId(1),
            id,
            body,
        };
        let sig = secret.sign(&req(5, 100, &body)).unwrap();
        assert_eq!(gate.admit(t(0), &req(5, 100, &ControlBody::List), None), Ok(()), "reads are open");
        assert_eq!(gate.admit(t(0), &req(5, 100, &body), None), Err(Refusal::Unsigned));
        assert_eq!(gate.admit(t(0), &req(6, 100, &body), Some(&sig)), Err(Refusal::BadSignature));
        assert_eq!(gate.admit(t(0), &req(5, 100, &body), Some(&sig)), Ok(()));
        assert_eq!(gate.admit(t(200), &req(5, 100, &body), Some(&sig)), Ok(()), "a retry");
        assert_eq!(gate.admit(t(11_000), &req(5, 100, &body), Some(&sig)), Err(Refusal::Replayed));
        let restarted =
            OperatorGate::new(secret.public(), gate.marks().map(|(n, id)| (n, ReplayWindow::after(id))).collect());
        let mut restarted = restarted;
        assert_eq!(
            restarted.admit(t(0), &req(5, 100, &body), Some(&sig)),
            Err(Refusal::Replayed),
            "after a restart with its marks"
        );
        let newer = secret.sign(&req(5, 101, &body)).unwrap();
        assert_eq!(restarted.admit(t(0), &req(5, 101, &body), Some(&newer)), Ok(()));
    }

    #[test]
    fn keygen_writes_a_secret_the_url_reads_and_never_overwrites() {
        let path = std::env::temp_dir().join(format!("ayllu-keygen-{}", std::process::id()));
        let _ = std::fs::remove_file(&path);
        let public = keygen(&path).unwrap();
        let secret = crate::udp_config::read_operator_secret(path.to_str().unwrap()).unwrap();
        assert_eq!(secret.public(), public);
        assert!(keygen(&path).is_err(), "an existing secret is never overwritten");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt as _;
            assert_eq!(std::fs::metadata(&path).unwrap().permissions().mode() & 0o777, 0o600);
        }
        std::fs::remove_file(&path).unwrap();
    }
}
