//! Network namespaces joined by a bridge ([`Netns::create`]) or by nothing yet
//! ([`Netns::bare`], for the userspace shaper's TAP interfaces), for tests whose processes
//! must use real subnet broadcast (loopback has none).
//!
//! Promises: namespace i (0-based) has address `10.SUBNET.0.(i+1)/24` with its broadcast
//! address `10.SUBNET.0.255` and a route for multicast (224.0.0.0/4) onto its interface (for
//! bare namespaces, once [`Netns::configure`] ran); everything created is removed when the
//! guard drops (links, then namespaces), whatever happened in between; names are unique per
//! test process and tag, so tests in one binary, and binaries run at the same time, do not
//! collide. Creating them needs root and `ip`: [`Netns::create`] says why it could not, and
//! callers skip loudly.

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
        let mut net = Netns::bare(tag, subnet, n)?;
        let tag = Netns::unique(tag);
        let bridge = format!("{tag}br");
        ip(&["link", "add", &bridge, "type", "bridge"])?;
        net.links.push(bridge.clone());
        ip(&["link", "set", &bridge, "up"])?;
        for i in 1..=n {
            let ns = net.ns(i - 1).to_owned();
            let (host, inner) = (format!("{tag}h{i}"), format!("{tag}c{i}"));
            ip(&["link", "add", &host, "type", "veth", "peer", "name", &inner])?;
            net.links.push(host.clone());
            ip(&["link", "set", &inner, "netns", &ns])?;
            ip(&["link", "set", &host, "master", &bridge])?;
            ip(&["link", "set", &host, "up"])?;
            net.configure(i - 1, &inner)?;
        }
        Ok(net)
    }

    /// `n` namespaces with nothing but loopback (up); [`Netns::configure`] addresses an
    /// interface put in them later (the shaper's TAP interfaces).
    pub fn bare(tag: &str, subnet: u8, n: usize) -> Result<Netns, String> {
        let tag = Netns::unique(tag);
        let mut net = Netns { subnet, namespaces: Vec::new(), links: Vec::new() };
        for i in 1..=n {
            let ns = format!("{tag}n{i}");
            ip(&["netns", "add", &ns])?;
            net.namespaces.push(ns.clone());
            ip(&["-n", &ns, "link", "set", "lo", "up"])?;
        }
        Ok(net)
    }

    /// `tag` made unique to this test process.
    fn unique(tag: &str) -> String {
        format!("{tag}{}", std::process::id() % 100_000)
    }

    /// Give interface `dev` of namespace `i` its address and broadcast address, bring it up,
    /// and route multicast onto it.
    pub fn configure(&self, i: usize, dev: &str) -> Result<(), String> {
        let ns = self.ns(i);
        ip(&["-n", ns, "addr", "add", &format!("{}/24", self.addr(i)), "brd", "+", "dev", dev])?;
        ip(&["-n", ns, "link", "set", dev, "up"])?;
        // Multicast (zero-config discovery) leaves by this interface: a namespace has no
        // default route, and the kernel needs one to send to 224.0.0.0/4.
        ip(&["-n", ns, "route", "add", "224.0.0.0/4", "dev", dev])
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
