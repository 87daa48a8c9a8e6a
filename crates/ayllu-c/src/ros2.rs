//! The ROS 2 body from C (`ayInitRos2Body` in ayllustd.h; docs/ros2.md): the node's body
//! behaviors (VISION, SONAR, BASE, or whatever the mapping file names) as ROS 2 topics, from a
//! mapping file. It is to a ROS 2 robot what `ay_sim_body` is to the simulator, so Fig. 2 moves
//! from one to the other by changing one line (examples/cmommt/c/cmommt.c: `AYLLU_ROS2_BODY`).
//!
//! Promises:
//! * `ay_ros2_body` is in every build of libayllu, so the header, and a program calling it,
//!   are the same whether or not the library has the body. Built without the cargo feature
//!   `ros2` (the default: the body brings a DDS stack of ~110 crates), it fails with
//!   `AY_ERR_INVALID` and a message that says how to build a library that has it;
//! * an error in the mapping file reaches C whole through `ay_last_error`: the file, where in
//!   it (`topic 2 (/robot2/scan), fields."ranges"`), what is wrong and what to write instead,
//!   exactly as `ayllu_ros2` words it;
//! * the arguments are checked the same way in both builds (a NULL or freed node, a NULL
//!   path), so a program's misuse does not hide behind the missing feature.

use std::ffi::c_char;

use crate::cstr::text;
use crate::node::{ay_node, with_node};
use crate::status::{ay_status, boundary, Fail};

/// What `ay_ros2_body` says in a library built without the ROS 2 body.
#[cfg(not(feature = "ros2"))]
const WITHOUT_ROS2: &str = "libayllu was built without the ROS 2 body: build it with `make ros2` (docs/ros2.md)";

/// Install the ROS 2 body the mapping file `mapping_file` describes on `node` (a path, relative
/// to the working directory; `{id}` in the file stands for the node's id, so one file serves a
/// fleet): the behaviors it names that the node lacks are created (VISION, SONAR, BASE for
/// Fig. 2), and from the node's next step on, samples of its "in" topics write their ports and
/// its "out" topics publish their ports' values. Call after the node is open
/// (`ayInitIPComms`) and before building the controller on the body's behaviors, as with
/// `ay_sim_body`.
///
/// Needs libayllu built with the ROS 2 body (cargo feature `ros2`: `make ros2`); without it,
/// the call fails with `AY_ERR_INVALID` and says so.
///
/// Ownership: borrows `mapping_file` for the call (nothing of it is kept).
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_INVALID` (path not UTF-8; a mapping file that is wrong: the message names the file,
/// the field and the fix; a mapped port the node has with another type; a library built
/// without the ROS 2 body), `AY_ERR_TRANSPORT` (the file cannot be read; the DDS stack
/// refused a participant, topic, reader or writer).
///
/// # Safety
/// `node` is NULL or a pointer from this library; `mapping_file` is NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_ros2_body(node: *mut ay_node, mapping_file: *const c_char) -> ay_status {
    boundary("ay_ros2_body", || {
        // SAFETY: the C caller's promise on `mapping_file`.
        let path = unsafe { text(mapping_file, "mapping_file") }?;
        with_node(node, |s| install(&mut s.node, path))
    })
}

#[cfg(feature = "ros2")]
fn install(node: &mut ayllu::Node, path: &str) -> Result<(), Fail> {
    ayllu_ros2::install_file(node, path).map_err(|e| {
        use ayllu_ros2::Error as E;
        // The status sorts the failure as recordings' are (a file that cannot be read is the
        // transport's, as are DDS refusals); the message is the body's own, whole.
        let status = match &e {
            E::Read { .. } | E::Ros2(_) => ay_status::AY_ERR_TRANSPORT,
            _ => ay_status::AY_ERR_INVALID,
        };
        Fail::new(status, e.to_string())
    })
}

#[cfg(not(feature = "ros2"))]
fn install(_node: &mut ayllu::Node, _path: &str) -> Result<(), Fail> {
    Err(Fail::invalid(WITHOUT_ROS2))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::node::{ay_node_free, ay_node_open};
    use std::ffi::{CStr, CString};

    fn last() -> String {
        // SAFETY: ay_last_error always returns a valid NUL-terminated string.
        unsafe { CStr::from_ptr(crate::status::ay_last_error()) }.to_string_lossy().into_owned()
    }

    fn open(id: u32) -> *mut ay_node {
        let url = CString::new(format!("mem://ros2-{id}")).unwrap();
        let mut node = std::ptr::null_mut();
        // SAFETY: a NUL-terminated URL and a valid output pointer.
        assert_eq!(unsafe { ay_node_open(id, url.as_ptr(), &mut node) }, ay_status::AY_OK, "{}", last());
        node
    }

    #[test]
    fn arguments_are_checked_in_every_build() {
        let file = CString::new("robot.toml").unwrap();
        // SAFETY: NULL handles and pointers are what is being tested; the path is valid.
        unsafe {
            assert_eq!(ay_ros2_body(std::ptr::null_mut(), file.as_ptr()), ay_status::AY_ERR_NULL);
            let node = open(1);
            assert_eq!(ay_ros2_body(node, std::ptr::null()), ay_status::AY_ERR_NULL);
            assert!(last().contains("mapping_file"), "{}", last());
            assert_eq!(ay_node_free(node), ay_status::AY_OK);
        }
    }

    #[cfg(not(feature = "ros2"))]
    #[test]
    fn without_the_feature_the_call_says_how_to_get_it() {
        let file = CString::new("robot.toml").unwrap();
        let node = open(2);
        // SAFETY: a live node and a NUL-terminated path.
        unsafe {
            assert_eq!(ay_ros2_body(node, file.as_ptr()), ay_status::AY_ERR_INVALID);
            assert_eq!(last(), format!("ay_ros2_body: {WITHOUT_ROS2}"));
            assert_eq!(ay_node_free(node), ay_status::AY_OK);
        }
    }

    #[cfg(feature = "ros2")]
    #[test]
    fn a_mapping_error_reaches_c_whole() {
        let dir = std::env::temp_dir().join(format!("ayllu-c-ros2-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("bad.toml");
        std::fs::write(
            &path,
            "[[topic]]\nname = \"scan\"\ntype = \"sensor_msgs/msg/LaserScan\"\ndirections = \"in\"\n",
        )
        .unwrap();
        let file = CString::new(path.to_str().unwrap()).unwrap();
        let missing = CString::new(dir.join("missing.toml").to_str().unwrap()).unwrap();
        let node = open(3);
        // SAFETY: a live node and NUL-terminated paths.
        unsafe {
            assert_eq!(ay_ros2_body(node, file.as_ptr()), ay_status::AY_ERR_INVALID);
            let message = last();
            assert!(message.starts_with(&format!("ay_ros2_body: {}: ", path.display())), "{message}");
            assert!(message.contains("unknown key `directions`: did you mean `direction`?"), "{message}");
            assert_eq!(ay_ros2_body(node, missing.as_ptr()), ay_status::AY_ERR_TRANSPORT);
            assert!(last().contains("missing.toml"), "{}", last());
            assert_eq!(ay_node_free(node), ay_status::AY_OK);
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}
