//! Operator signatures (N5, docs/security.md): who may rewire a team, apart from who holds its
//! key.
//!
//! A team key is shared by every robot, so in a keyed team any robot — or anyone who took one
//! apart — could rewire every other. A node started with an *operator public key* accepts
//! structure changes (CONNECT, DISCONNECT) only in REQUESTs signed with the matching secret,
//! which stays with the operator's tools. The signature is Ed25519 over
//! [`SignedRequest::bytes`]: a context string, the team, the requester, the **receiver** and
//! the request as encoded, so a signed request cannot be re-aimed at another team, another
//! node, or under another requester's id. Freshness (a captured signed request replayed later)
//! is the receiver's to check, by the request id (`spec/protocol.md`, "Operator signature").
//!
//! Promises: verification never panics on any bytes; a secret never appears in `Debug` output.

use core::fmt;

use ayllu_core::{ControlBody, NodeId};
use ed25519_dalek::{Signature, Signer, SigningKey, VerifyingKey};

use crate::encode::{put_request, EncodeError};

/// Bytes of an operator signature on the wire.
pub const SIGNATURE_LEN: usize = 64;
/// Bytes of an operator secret (the Ed25519 seed) and of an operator public key.
pub const OPERATOR_KEY_LEN: usize = 32;
/// The tag byte that introduces a signature after a REQUEST's arguments.
pub const SIGNATURE_TAG: u8 = 1;

/// An Ed25519 signature over a request.
pub type OperatorSignature = [u8; SIGNATURE_LEN];

/// What every signed byte string starts with, so an operator signature can never be taken for
/// a signature over something else made with the same key.
const CONTEXT: &[u8] = b"ayllu operator request v1\0";

/// What an operator signature covers: request `id` asking `body` of node `receiver`, sent by
/// `requester` in `team`.
#[derive(Clone, Copy, Debug)]
pub struct SignedRequest<'a> {
    /// The team id of the datagram.
    pub team: u32,
    /// The requesting node (the datagram's sender).
    pub requester: NodeId,
    /// The node asked (so a signed request cannot be re-aimed at another node).
    pub receiver: NodeId,
    /// The request's id (its freshness is the receiver's to check).
    pub id: u64,
    /// What is asked.
    pub body: &'a ControlBody,
}

impl SignedRequest<'_> {
    /// The bytes the signature covers: the context, `team`, `requester` and `receiver` (each
    /// `u32` LE), then the REQUEST body as encoded (`id` and the operation with its
    /// arguments), without the signature itself.
    pub fn bytes(&self) -> Result<Vec<u8>, EncodeError> {
        let mut b = Vec::with_capacity(CONTEXT.len() + 12 + 8 + 64);
        b.extend_from_slice(CONTEXT);
        b.extend_from_slice(&self.team.to_le_bytes());
        b.extend_from_slice(&self.requester.0.to_le_bytes());
        b.extend_from_slice(&self.receiver.0.to_le_bytes());
        b.extend_from_slice(&self.id.to_le_bytes());
        put_request(&mut b, self.body)?;
        Ok(b)
    }
}

/// The operator's secret: signs requests. Kept by the operator's tools, never by robots.
#[derive(Clone, PartialEq, Eq)]
pub struct OperatorSecret(SigningKey);

impl OperatorSecret {
    /// The secret whose Ed25519 seed is `seed` (32 bytes, e.g. from `ayllu keygen`).
    pub fn from_seed(seed: &[u8; OPERATOR_KEY_LEN]) -> Self {
        OperatorSecret(SigningKey::from_bytes(seed))
    }

    /// The seed, to store it.
    pub fn to_seed(&self) -> [u8; OPERATOR_KEY_LEN] {
        self.0.to_bytes()
    }

    /// The public key robots are given.
    pub fn public(&self) -> OperatorPublic {
        OperatorPublic(self.0.verifying_key())
    }

    /// Sign `request`.
    pub fn sign(&self, request: &SignedRequest<'_>) -> Result<OperatorSignature, EncodeError> {
        Ok(self.0.sign(&request.bytes()?).to_bytes())
    }
}

impl fmt::Debug for OperatorSecret {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // Never the secret: debug output ends up in logs.
        write!(f, "OperatorSecret(public {})", self.public())
    }
}

/// The operator's public key: a node that holds it accepts structure changes only when
/// signed with the matching [`OperatorSecret`].
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct OperatorPublic(VerifyingKey);

impl OperatorPublic {
    /// The key from its 32 bytes; `None` if they are not a valid Ed25519 point.
    pub fn from_bytes(bytes: &[u8; OPERATOR_KEY_LEN]) -> Option<Self> {
        VerifyingKey::from_bytes(bytes).ok().map(OperatorPublic)
    }

    /// The key from 64 hex digits (either case), as tools print and accept it.
    pub fn from_hex(hex: &str) -> Option<Self> {
        Self::from_bytes(&crate::auth::parse_key_hex(hex)?)
    }

    /// The key's 32 bytes.
    pub fn to_bytes(&self) -> [u8; OPERATOR_KEY_LEN] {
        self.0.to_bytes()
    }

    /// Whether `signature` is this key's signature of `request`. Strict verification (no
    /// malleable signatures); never panics.
    pub fn verify(&self, request: &SignedRequest<'_>, signature: &OperatorSignature) -> bool {
        let Ok(bytes) = request.bytes() else { return false };
        self.0.verify_strict(&bytes, &Signature::from_bytes(signature)).is_ok()
    }
}

impl fmt::Display for OperatorPublic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for b in self.to_bytes() {
            write!(f, "{b:02x}")?;
        }
        Ok(())
    }
}

impl fmt::Debug for OperatorPublic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "OperatorPublic({self})")
    }
}

/// Whether a request changes the receiver's structure, the right an operator key guards: the
/// core's one list ([`ControlBody::changes_structure`]), which its access rules use too.
pub fn changes_structure(body: &ControlBody) -> bool {
    body.changes_structure()
}

#[cfg(test)]
mod tests {
    use super::*;
    use ayllu_core::ConnectionId;

    #[test]
    fn rfc8032_test_1_public_key() {
        // RFC 8032, section 7.1, TEST 1: the seed and its public key.
        let seed =
            crate::auth::parse_key_hex("9d61b19deffd5a60ba844af492ec2cc44449c5697b326919703bac031cae7f60").unwrap();
        let secret = OperatorSecret::from_seed(&seed);
        assert_eq!(secret.public().to_string(), "d75a980182b10ab7d54bfed3c964073a0ee172f3daa62325af021a68f707511a");
        assert!(!format!("{secret:?}").contains("9d61b1"), "Debug never shows the secret");
    }

    #[test]
    fn a_signature_binds_team_requester_receiver_and_request() {
        let secret = OperatorSecret::from_seed(&[7; 32]);
        let public = secret.public();
        let body = ControlBody::Disconnect { conn: ConnectionId(4) };
        let req = |team, requester, receiver, id, body| SignedRequest {
            team,
            requester: NodeId(requester),
            receiver: NodeId(receiver),
            id,
            body,
        };
        let sig = secret.sign(&req(9, 1, 2, 77, &body)).unwrap();
        assert!(public.verify(&req(9, 1, 2, 77, &body), &sig));
        assert!(!public.verify(&req(8, 1, 2, 77, &body), &sig), "another team");
        assert!(!public.verify(&req(9, 3, 2, 77, &body), &sig), "another requester");
        assert!(!public.verify(&req(9, 1, 3, 77, &body), &sig), "another receiver");
        assert!(!public.verify(&req(9, 1, 2, 78, &body), &sig), "another id");
        let other = ControlBody::Disconnect { conn: ConnectionId(5) };
        assert!(!public.verify(&req(9, 1, 2, 77, &other), &sig), "another request");
        let mut bent = sig;
        bent[10] ^= 1;
        assert!(!public.verify(&req(9, 1, 2, 77, &body), &bent));
        let stranger = OperatorSecret::from_seed(&[8; 32]).public();
        assert!(!stranger.verify(&req(9, 1, 2, 77, &body), &sig), "another operator");
        assert!(!public.verify(&req(9, 1, 2, 77, &body), &[0; 64]));
        assert!(!public.verify(&req(9, 1, 2, 77, &body), &[0xff; 64]));
    }

    #[test]
    fn public_keys_from_hex() {
        let public = OperatorSecret::from_seed(&[1; 32]).public();
        assert_eq!(OperatorPublic::from_hex(&public.to_string()), Some(public));
        assert_eq!(OperatorPublic::from_hex(&public.to_string().to_uppercase()), Some(public));
        assert_eq!(OperatorPublic::from_hex("00"), None);
    }
}
