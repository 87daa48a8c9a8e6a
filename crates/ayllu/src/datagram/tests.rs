//! Tests of [`OsSocket`] on loopback (read-ahead, segmented sends, how long an empty finding
//! stands, when a wait polls) and of the in-memory bus against it: the promises in
//! `datagram/mod.rs`, held by the real kernel.

use super::os_socket::{READ_AHEAD, SLOT, STREAK};
use super::*;

/// A receiving and a sending socket on fresh loopback ports.
fn loopback_pair() -> (OsSocket, OsSocket) {
    let loopback: SocketAddr = "127.0.0.1:0".parse().unwrap();
    (OsSocket::bind(loopback).unwrap(), OsSocket::bind(loopback).unwrap())
}

/// The read-ahead hands out every datagram once, in order, with its sender and length
/// (a longer one than accepted cut to `SLOT`), across more than one batch.
#[test]
fn os_socket_reads_ahead_without_losing_or_reordering() {
    let (mut rx, mut tx) = loopback_pair();
    let (to, from) = (rx.local_addr().unwrap(), tx.local_addr().unwrap());
    let sizes: Vec<usize> = (0..3 * READ_AHEAD + 5).map(|i| if i == 7 { SLOT + 100 } else { 1 + i * 37 }).collect();
    for (i, &n) in sizes.iter().enumerate() {
        tx.send_to(&vec![i as u8; n], to).unwrap();
    }
    let mut buf = vec![0u8; SLOT];
    for (i, &n) in sizes.iter().enumerate() {
        rx.wait(StdDuration::from_secs(1));
        let (len, sender) = rx.recv_from(&mut buf).unwrap().expect("datagram waiting");
        assert_eq!((len, sender), (n.min(SLOT), from), "datagram {i}");
        assert!(buf[..len].iter().all(|&b| b == i as u8), "datagram {i} content");
    }
    // Nothing left: asked twice, since the first answer may come from the read-ahead.
    assert_eq!(rx.recv_from(&mut buf).unwrap(), None);
    assert_eq!(rx.recv_from(&mut buf).unwrap(), None);
    let t = std::time::Instant::now();
    rx.wait(StdDuration::from_millis(20));
    assert!(t.elapsed() >= StdDuration::from_millis(15), "wait returned early with nothing to read");
}

/// A segmented send the kernel refuses (here: more than one UDP payload in all) is sent
/// one datagram per call instead, and the socket does not try segmenting again.
#[cfg(target_os = "linux")]
#[test]
fn a_refused_segmented_send_goes_one_datagram_per_call() {
    let (mut rx, mut tx) = loopback_pair();
    let train: Vec<u8> = (0..2 * 40_000).map(|i| (i / 40_000) as u8 + 1).collect();
    tx.send_segments(&train, 40_000, rx.local_addr().unwrap()).unwrap();
    assert!(!tx.segmented, "80 000 bytes in one send is refused (EMSGSIZE): segmenting is off");
    let mut buf = vec![0u8; SLOT];
    for i in 1..=2u8 {
        rx.wait(StdDuration::from_secs(1));
        let (len, from) = rx.recv_from(&mut buf).unwrap().expect("datagram waiting");
        // Longer than a receiver accepts, so cut to SLOT, as any receive would.
        assert_eq!((len, from), (SLOT, tx.local_addr().unwrap()), "datagram {i}");
        assert!(buf[..len].iter().all(|&b| b == i), "datagram {i} content");
    }
}

/// RECHECK is counted in turn time: an empty finding stands within a turn and for turns
/// less than RECHECK later, and no longer; a wait that emptied the socket counts from the
/// next turn, and a later wait that heard something undoes that.
#[test]
fn an_empty_finding_stands_for_recheck_of_turn_time() {
    let (mut rx, mut tx) = loopback_pair();
    let to = rx.local_addr().unwrap();
    let mut buf = vec![0u8; SLOT];
    let t = |us: u64| Instant::ZERO + ayllu_core::Duration::from_micros(us);
    rx.set_recheck(RECHECK);
    rx.set_turn_time(t(1_000));
    assert_eq!(rx.recv_from(&mut buf).unwrap(), None, "nothing sent yet");
    tx.send_to(b"a", to).unwrap();
    // The datagram is in the socket (loopback delivers within the send), but the finding
    // stands for the rest of the turn and the next turn 19 us later.
    assert_eq!(rx.recv_from(&mut buf).unwrap(), None, "same turn");
    rx.set_turn_time(t(1_019));
    assert_eq!(rx.recv_from(&mut buf).unwrap(), None, "19 us later");
    rx.set_turn_time(t(1_020));
    assert_eq!(rx.recv_from(&mut buf).unwrap().map(|(n, _)| n), Some(1), "20 us later: asked again");
    // A blocking wait (>= 20 ms) that reads the socket empty: the next turn's later
    // receives do not ask again within RECHECK...
    tx.send_to(b"b", to).unwrap();
    rx.wait(StdDuration::from_secs(1));
    rx.set_turn_time(t(5_000));
    assert_eq!(rx.recv_from(&mut buf).unwrap().map(|(n, _)| n), Some(1), "what the wait read");
    tx.send_to(b"c", to).unwrap();
    assert_eq!(rx.recv_from(&mut buf).unwrap(), None, "the wait's finding stands");
    // ...but a short wait (ppoll) that finds something makes the next receive ask.
    rx.wait(StdDuration::from_millis(5));
    assert_eq!(rx.recv_from(&mut buf).unwrap().map(|(n, _)| n), Some(1), "after the short wait");
}

/// Empty findings in a row stand longer and longer (RECHECK, then doubled up to
/// RECHECK_DOUBLINGS times), and a read that finds datagrams starts again from RECHECK.
#[test]
fn empty_findings_in_a_row_stand_longer_up_to_a_bound() {
    let (mut rx, mut tx) = loopback_pair();
    let to = rx.local_addr().unwrap();
    let mut buf = vec![0u8; SLOT];
    let t = |us: u64| Instant::ZERO + ayllu_core::Duration::from_micros(us);
    rx.set_recheck(RECHECK);
    // Found empty at 0 (stands 20 us), 20 (40), 60 (80), 140 (160), 300 (160: the bound).
    let mut at = 0;
    for stands in [20, 40, 80, 160, 160] {
        rx.set_turn_time(t(at));
        assert_eq!(rx.recv_from(&mut buf).unwrap(), None, "empty at {at}");
        at += stands;
    }
    tx.send_to(b"a", to).unwrap();
    rx.set_turn_time(t(at - 1));
    assert_eq!(rx.recv_from(&mut buf).unwrap(), None, "the last finding stands 160 us");
    rx.set_turn_time(t(at));
    assert_eq!(rx.recv_from(&mut buf).unwrap().map(|(n, _)| n), Some(1), "asked again at {at}");
    // That read emptied the socket: its finding stands RECHECK again, not 160 us.
    tx.send_to(b"b", to).unwrap();
    rx.set_turn_time(t(at + 19));
    assert_eq!(rx.recv_from(&mut buf).unwrap(), None, "19 us after the read");
    rx.set_turn_time(t(at + 20));
    assert_eq!(rx.recv_from(&mut buf).unwrap().map(|(n, _)| n), Some(1), "20 us after the read");
}

/// While datagrams stream in, a wait polls before it sleeps, and reads what came; a poll
/// that finds nothing ends the streak (the next wait sleeps at once). A socket on a manual
/// clock (no RECHECK) never polls, however close its reads come.
#[test]
fn a_wait_polls_only_while_datagrams_stream_in() {
    let (mut rx, mut tx) = loopback_pair();
    let to = rx.local_addr().unwrap();
    let mut buf = vec![0u8; SLOT];
    // Manual clock: reads build no streak.
    for i in 0..4u8 {
        tx.send_to(&[i], to).unwrap();
        assert_eq!(rx.recv_from(&mut buf).unwrap().map(|(n, _)| n), Some(1));
    }
    assert_eq!((rx.streak, rx.last_data), (0, None), "no streak on a manual clock");
    // Real time, a stream (set as a read a moment ago would leave it): the wait's poll
    // reads the datagram and keeps the streak going.
    rx.set_recheck(RECHECK);
    let before = std::time::Instant::now();
    rx.streak = STREAK;
    rx.last_data = Some(before);
    tx.send_to(b"s", to).unwrap();
    rx.wait(StdDuration::from_secs(1));
    assert!(rx.ahead.pending(), "the poll read the datagram");
    assert!(rx.last_data.is_some_and(|t| t > before), "the poll's read was recorded");
    assert_eq!(rx.recv_from(&mut buf).unwrap().map(|(n, _)| n), Some(1));
    // Having sent, the socket waits for what may be the answer without polling.
    rx.streak = STREAK;
    rx.send_to(b"q", tx.local_addr().unwrap()).unwrap();
    rx.wait(StdDuration::from_millis(1));
    assert_eq!(rx.streak, STREAK, "no poll after a send, so the streak stands");
    rx.sent_since_read = false;
    // Nothing comes: the poll gives up after SPIN, the streak ends, and the wait sleeps
    // out its time as any wait does.
    rx.streak = STREAK;
    rx.wait(StdDuration::from_millis(1));
    assert_eq!(rx.streak, 0, "a poll that found nothing ends the streak");
    tx.send_to(b"t", to).unwrap();
    rx.wait(StdDuration::from_secs(1));
    assert_eq!(rx.recv_from(&mut buf).unwrap().map(|(n, _)| n), Some(1), "the sleeping wait hears it");
}

/// `spin_us=0` (`set_spin(0)`): on a real-time clock too, no two reads are ever close
/// enough to make a stream, so a read ends any streak and no wait polls.
#[test]
fn a_spin_of_zero_never_makes_a_stream() {
    let (mut rx, mut tx) = loopback_pair();
    let to = rx.local_addr().unwrap();
    let mut buf = vec![0u8; SLOT];
    rx.set_recheck(RECHECK);
    rx.set_spin(StdDuration::ZERO);
    for i in 0..4u8 {
        // As if a stream had been running: the read must end it all the same.
        (rx.streak, rx.last_data) = (STREAK, Some(std::time::Instant::now()));
        tx.send_to(&[i], to).unwrap();
        rx.wait(StdDuration::from_secs(1));
        assert_eq!(rx.recv_from(&mut buf).unwrap().map(|(n, _)| n), Some(1));
        assert_eq!(rx.streak, 0, "read {i}");
    }
}

/// A train sent in one call arrives as the very datagrams it holds, in order, with the
/// sender's address: the kernel's segmented send (Linux) and the trait's default (one
/// `send_to` each, here on the in-memory bus) alike.
#[test]
fn segments_arrive_as_the_datagrams_they_hold() {
    let sizes = [1430usize, 1430, 1430, 208];
    let mut train = Vec::new();
    for (i, &n) in sizes.iter().enumerate() {
        train.extend((0..n).map(|j| (i * 31 + j) as u8));
    }
    let (mut rx, mut tx) = loopback_pair();
    let bus = DatagramBus::new();
    let (mut brx, mut btx) =
        (bus.bind("10.0.0.1:1".parse().unwrap()).unwrap(), bus.bind("10.0.0.2:1".parse().unwrap()).unwrap());
    tx.send_segments(&train, 1430, rx.local_addr().unwrap()).unwrap();
    btx.send_segments(&train, 1430, brx.local_addr().unwrap()).unwrap();
    let receivers: [(&mut dyn DatagramSocket, SocketAddr); 2] =
        [(&mut rx, tx.local_addr().unwrap()), (&mut brx, btx.local_addr().unwrap())];
    for (socket, from) in receivers {
        let mut buf = vec![0u8; SLOT];
        let mut at = 0;
        for (i, &n) in sizes.iter().enumerate() {
            socket.wait(StdDuration::from_secs(1));
            let (len, sender) = socket.recv_from(&mut buf).unwrap().expect("datagram waiting");
            assert_eq!((len, sender), (n, from), "datagram {i}");
            assert_eq!(&buf[..len], &train[at..at + n], "datagram {i} content");
            at += n;
        }
        assert_eq!(socket.recv_from(&mut buf).unwrap(), None, "nothing more");
    }
}

/// A receive that found nothing may stand for a while (a real-time node's RECHECK), but a
/// wait always reads what has arrived since, whether it waits in `ppoll` (short waits) or
/// in the receive itself (long ones).
#[test]
fn os_socket_wait_hears_what_came_after_an_empty_receive() {
    let (mut rx, mut tx) = loopback_pair();
    let to = rx.local_addr().unwrap();
    let mut buf = vec![0u8; SLOT];
    for (i, (recheck, wait)) in [
        (RECHECK, StdDuration::from_millis(5)),
        (RECHECK, StdDuration::from_secs(1)),
        (StdDuration::from_secs(3600), StdDuration::from_secs(60)),
        (StdDuration::ZERO, StdDuration::from_secs(1)),
    ]
    .into_iter()
    .enumerate()
    {
        rx.set_recheck(recheck);
        assert_eq!(rx.recv_from(&mut buf).unwrap(), None, "case {i}: nothing sent yet");
        tx.send_to(&[i as u8; 3], to).unwrap();
        rx.wait(wait);
        let (len, _) = rx.recv_from(&mut buf).unwrap().expect("the wait read the datagram");
        assert_eq!(&buf[..len], &[i as u8; 3], "case {i}");
    }
}
