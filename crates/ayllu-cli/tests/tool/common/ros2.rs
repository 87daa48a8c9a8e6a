//! Shared by the ROS 2 body's tests (`ros2_*.rs`, built with `--features ros2` by
//! `make test-ros2`): a network namespace of the test's own for DDS, and the independent ROS 2
//! peer (Cyclone DDS from Python, `crates/ayllu-ros2/tests/ros2_peer/`) as child processes.
//!
//! Promises: [`own_network`] moves the calling test thread (and every process and thread it
//! starts afterwards) into a new network namespace with only loopback, multicast enabled on
//! it: DDS discovery (multicast to 239.255.0.1) and all its traffic stay inside, no two tests
//! meet, and nothing leaves the machine. It needs root and `ip`; without them it fails the test
//! naming what is missing (a test never passes by skipping). [`peer`] commands run the Python
//! peer with the Cyclone DDS configuration of `dds_env.py` (unicast discovery on 127.0.0.1,
//! which RustDDS also probes), and fail naming `make test-ros2` when cyclonedds is missing.

#![allow(dead_code)]

use std::path::PathBuf;
use std::process::Command;

/// Move this thread into a network namespace of its own (module docs). Call it first in the
/// test, before anything starts a thread or a process.
pub fn own_network() {
    // SAFETY: unshare(CLONE_NEWNET) takes no pointers; it moves the calling thread (tests run
    // each on its own thread) into a new network namespace, which later threads and children
    // of this thread inherit.
    let r = unsafe { libc::unshare(libc::CLONE_NEWNET) };
    assert_eq!(
        r,
        0,
        "the ROS 2 tests run in a network namespace of their own and need root (CAP_SYS_ADMIN): unshare: {}",
        std::io::Error::last_os_error()
    );
    for args in [
        &["link", "set", "lo", "up"][..],
        &["link", "set", "lo", "multicast", "on"],
        &["route", "add", "224.0.0.0/4", "dev", "lo"],
    ] {
        let out = Command::new("ip").args(args).output().unwrap_or_else(|e| panic!("running ip (iproute2): {e}"));
        assert!(out.status.success(), "ip {}: {}", args.join(" "), String::from_utf8_lossy(&out.stderr));
    }
}

/// The folder of the Python ROS 2 peer.
pub fn peer_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../ayllu-ros2/tests/ros2_peer")
}

/// The Python that runs the peer (`$PYTHON`, else `python3`), checked to have cyclonedds.
pub fn python() -> String {
    let python = std::env::var("PYTHON").unwrap_or_else(|_| "python3".to_owned());
    let ok = Command::new(&python).args(["-c", "import cyclonedds"]).output().is_ok_and(|o| o.status.success());
    assert!(
        ok,
        "{python} has no cyclonedds: `make test-ros2` installs it (pip install -r crates/ayllu-ros2/tests/ros2_peer/requirements.txt)"
    );
    python
}

/// The Cyclone DDS configuration every peer and body of a test uses on `domain`.
pub fn cyclone_uri(domain: u16) -> String {
    let out = Command::new(python())
        .current_dir(peer_dir())
        .args(["-c", &format!("import dds_env; print(dds_env.cyclone_uri({domain}))")])
        .output()
        .expect("running dds_env.py");
    assert!(out.status.success(), "dds_env.py: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).trim().to_owned()
}

/// `python3 ros2_peer/SCRIPT args...` on ROS domain `domain`.
pub fn peer(script: &str, domain: u16, args: &[&str]) -> Command {
    let mut cmd = Command::new(python());
    cmd.current_dir(peer_dir())
        .arg(script)
        .args(["--domain", &domain.to_string()])
        .args(args)
        .env("CYCLONEDDS_URI", cyclone_uri(domain))
        .env("ROS_DOMAIN_ID", domain.to_string());
    cmd
}

/// Write `text` into a fresh temporary file named `name` and return its path.
pub fn temp_file(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("ayllu-ros2-test-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join(name);
    std::fs::write(&path, text).expect("writing a temp file");
    path
}
