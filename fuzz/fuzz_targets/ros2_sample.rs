//! Fuzz target: arbitrary bytes as a ROS 2 sample of every message type the ROS 2 body knows
//! (crates/ayllu-ros2/src/messages.rs), through the same CDR code RustDDS runs for
//! `Subscription::take_seed`.
//!
//! Promises checked, beyond "no panic, no unbounded allocation or loop": the first byte picks
//! the type (every type is reached); a failed decode always leaves a cause (the body counts a
//! dropped sample by it); a decoded sample re-encodes, and the re-encoded bytes decode to a
//! sample that encodes to the same bytes (the body can publish whatever it takes, and the two agree).
#![no_main]

use std::cell::Cell;
use std::marker::PhantomData;

use ayllu_ros2::messages::{message_types, Decode, Encoded, Sample};
use libfuzzer_sys::fuzz_target;
use ros2_client::dds::rustdds::no_key::{DeserializerAdapter, SerializerAdapter};
use ros2_client::dds::rustdds::serialization::CdrDeserializeSeedDecoder;
use ros2_client::dds::rustdds::{CDRDeserializerAdapter, CDRSerializerAdapter, RepresentationIdentifier};

fn decode(ty: &'static ayllu_ros2::messages::MessageType, bytes: &[u8]) -> Result<Sample, ()> {
    let cause = Cell::new(None);
    let seed = Decode { ty, max_elements: 4096, cause: &cause };
    let decoder = CdrDeserializeSeedDecoder::new(seed, PhantomData::<()>);
    match CDRDeserializerAdapter::<Sample>::from_bytes_with(bytes, RepresentationIdentifier::CDR_LE, decoder) {
        Ok(s) => Ok(s),
        Err(_) => {
            assert!(cause.get().is_some(), "a failed decode of {} left no cause", ty.name());
            Err(())
        }
    }
}

fuzz_target!(|data: &[u8]| {
    let types: Vec<_> = message_types().collect();
    let Some((&pick, bytes)) = data.split_first() else { return };
    let ty = types[usize::from(pick) % types.len()];
    if let Ok(sample) = decode(ty, bytes) {
        // What a body publishes: the same adapter as `Publisher<Encoded>` (CDR, little-endian).
        // Compared as bytes, not samples: a NaN is never equal to itself.
        let encode = |s: &Sample| {
            CDRSerializerAdapter::<Encoded>::to_bytes(&Encoded(s.clone())).expect("a decoded sample re-encodes")
        };
        let again = encode(&sample);
        let back = decode(ty, &again).unwrap_or_else(|()| panic!("{} does not decode what it encoded", ty.name()));
        assert_eq!(encode(&back), again, "{} re-encoded differently", ty.name());
    }
});
