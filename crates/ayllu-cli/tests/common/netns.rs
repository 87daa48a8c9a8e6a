//! Network namespaces on one bridge, for tests whose processes must use real subnet broadcast
//! (loopback has none).
//!
//! Promises: namespace i (0-based) has address `10.SUBNET.0.(i+1)/24` with its broadcast
//! address `10.SUBNET.0.255` and a route for multicast (224.0.0.0/4) onto the bridge; everything created is removed when the guard drops (links, then
//! namespaces), whatever happened in between; names are unique per test process and tag, so
//! tests in one binary, and binaries run at the same time, do not collide. Creating them needs
//! root and `ip`: [`Netns::create`] says why it could not, and callers skip loudly.

use std::process::Command;

/// The namespaces and the links joining them; removed on drop.
pub struct Netns {
    subnet: u8,
    namespaces: Vec<String>,
    links: Vec<String>,
}

fn ip(args: &[&str]) -> Result<(), String> {
    let out = Command::new("ip").args(args).output().map_err(|e| format!("running ip: {e}"))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!("ip {}: {}", args.join(" "), String::from_utf8_lossy(&out.stderr).trim()))
    }
}

impl Netns {
    /// `n` namespaces on a new bridge, in `10.subnet.0.0/24`. `tag` (two letters) keeps the
    /// names of different tests apart; interface names stay within 15 bytes.
    pub fn create(tag: &str, subnet: u8, n: usize) -> Result<Netns, String> {
        let tag = format!("{tag}{}", std::process::id() % 100_000);
        let mut net = Netns { subnet, namespaces: Vec::new(), links: Vec::new() };
        let bridge = format!("{tag}br");
        ip(&["link", "add", &bridge, "type", "bridge"])?;
        net.links.push(bridge.clone());
        ip(&["link", "set", &bridge, "up"])?;
        for i in 1..=n {
            let ns = format!("{tag}n{i}");
            ip(&["netns", "add", &ns])?;
            net.namespaces.push(ns.clone());
            let (host, inner) = (format!("{tag}h{i}"), format!("{tag}c{i}"));
            ip(&["link", "add", &host, "type", "veth", "peer", "name", &inner])?;
            net.links.push(host.clone());
            ip(&["link", "set", &inner, "netns", &ns])?;
            ip(&["link", "set", &host, "master", &bridge])?;
            ip(&["link", "set", &host, "up"])?;
            ip(&["-n", &ns, "addr", "add", &format!("{}/24", net.addr(i - 1)), "brd", "+", "dev", &inner])?;
            ip(&["-n", &ns, "link", "set", &inner, "up"])?;
            ip(&["-n", &ns, "link", "set", "lo", "up"])?;
            // Multicast (zero-config discovery) leaves by the bridge: a namespace has no
            // default route, and the kernel needs one to send to 224.0.0.0/4.
            ip(&["-n", &ns, "route", "add", "224.0.0.0/4", "dev", &inner])?;
        }
        Ok(net)
    }

    /// The name of namespace `i`.
    pub fn ns(&self, i: usize) -> &str {
        &self.namespaces[i]
    }

    /// The address of namespace `i`.
    pub fn addr(&self, i: usize) -> String {
        format!("10.{}.0.{}", self.subnet, i + 1)
    }

    /// The subnet's broadcast address.
    pub fn broadcast(&self) -> String {
        format!("10.{}.0.255", self.subnet)
    }

    /// Run `program args...` inside namespace `i` to completion (e.g. `nft` rules for loss and
    /// partitions); `Err` with its stderr if it fails or cannot start.
    pub fn exec(&self, i: usize, program: &str, args: &[&str]) -> Result<(), String> {
        let out = self.command(i, program).args(args).output().map_err(|e| format!("running {program}: {e}"))?;
        if out.status.success() {
            Ok(())
        } else {
            Err(format!("{program} {}: {}", args.join(" "), String::from_utf8_lossy(&out.stderr).trim()))
        }
    }

    /// `program args...` run inside namespace `i` (`ip netns exec` execs it: same pid).
    pub fn command(&self, i: usize, program: &str) -> Command {
        let mut cmd = Command::new("ip");
        cmd.args(["netns", "exec", self.ns(i), program]);
        cmd
    }
}

impl Drop for Netns {
    fn drop(&mut self) {
        // Deleting a veth end deletes its peer at once (namespace teardown is asynchronous).
        for l in self.links.iter().rev() {
            let _ = ip(&["link", "del", l]);
        }
        for ns in &self.namespaces {
            let _ = ip(&["netns", "del", ns]);
        }
    }
}
