#!/usr/bin/env python3
"""Loopback-only Cyclone DDS configuration for the ROS 2 test peers.

What it is for: every script in this folder (and any test that starts them) runs
Cyclone DDS with the configuration returned by `cyclone_env(domain)`, so that
DDS traffic stays on the loopback interface and parallel runs on other domain
ids never mix.

What it promises:

* Only `lo` is used (`NetworkInterface name="lo"`), multicast is off
  (`AllowMulticast false`): `lo` has no MULTICAST flag on a stock Linux host,
  and a RustDDS participant does not join 239.255.0.1 on an interface without
  that flag, so multicast would not reach it anyway.
* Discovery is unicast to 127.0.0.1 (`Peers/Peer address="127.0.0.1"`): Cyclone
  sends SPDP to the well-known unicast discovery port of every participant
  index 0..MaxAutoParticipantIndex, i.e. 7400 + 250*domain + 10 + 2*index.
* `ParticipantIndex auto` makes Cyclone bind those well-known ports itself, so a
  RustDDS participant (which sends SPDP to 127.0.0.1 at the ports of indices
  0..11, its SPDP_LOCALHOST_PEER_COUNT) finds it too. With
  `MaxAutoParticipantIndex` 11 (the default here) at most 12 participants, of
  any implementation, can share one domain on this host; a 13th Cyclone
  participant fails to start, loudly, rather than being silently undiscovered.
* The XML applies to any domain id (`Domain id="any"`: a participant created
  on another id than the one given would otherwise fall back to Cyclone's
  defaults, multicast on the default interface); the id itself is passed as
  `ROS_DOMAIN_ID` and by the scripts' `--domain`.
* `ensure_loopback(domain)` sets CYCLONEDDS_URI in this process when it is
  unset, so that a script started by hand does not use Cyclone's defaults.

Library use: `from dds_env import cyclone_env, cyclone_uri`; command line:
`python3 dds_env.py DOMAIN` prints `export` lines for a shell.
"""

from __future__ import annotations

import os
import shlex
import sys

# RustDDS 0.15.1 probes 127.0.0.1 at the SPDP ports of participant ids 0..11.
RUSTDDS_LOCALHOST_PEERS = 12


def spdp_unicast_port(domain: int, index: int) -> int:
    """RTPS well-known unicast discovery port (RTPS 2.5, 9.6.2.3)."""
    return 7400 + 250 * domain + 10 + 2 * index


def cyclone_uri(domain: int, max_participants: int = RUSTDDS_LOCALHOST_PEERS) -> str:
    """The CYCLONEDDS_URI XML for a loopback-only, unicast-discovery domain.

    `domain` is only checked (0..232 keeps every RTPS port below 65536); the XML
    itself applies to any domain id.
    """
    if not 0 <= domain <= 232:
        raise ValueError(f"domain id {domain} out of range 0..232")
    if max_participants < 1:
        raise ValueError("max_participants must be at least 1")
    return (
        "<CycloneDDS>"
        '<Domain id="any">'
        "<General>"
        '<Interfaces><NetworkInterface name="lo"/></Interfaces>'
        "<AllowMulticast>false</AllowMulticast>"
        "</General>"
        "<Discovery>"
        "<ParticipantIndex>auto</ParticipantIndex>"
        f"<MaxAutoParticipantIndex>{max_participants - 1}</MaxAutoParticipantIndex>"
        '<Peers><Peer address="127.0.0.1"/></Peers>'
        "</Discovery>"
        "</Domain>"
        "</CycloneDDS>"
    )


def ensure_loopback(domain: int) -> str:
    """Set CYCLONEDDS_URI for this process unless the caller already set it."""
    return os.environ.setdefault("CYCLONEDDS_URI", cyclone_uri(domain))


def cyclone_env(
    domain: int,
    base: dict[str, str] | None = None,
    max_participants: int = RUSTDDS_LOCALHOST_PEERS,
) -> dict[str, str]:
    """A copy of `base` (default: os.environ) with CYCLONEDDS_URI, ROS_DOMAIN_ID."""
    env = dict(os.environ if base is None else base)
    env["CYCLONEDDS_URI"] = cyclone_uri(domain, max_participants)
    env["ROS_DOMAIN_ID"] = str(domain)
    return env


def main(argv: list[str]) -> int:
    if len(argv) != 2 or not argv[1].isdigit():
        print("usage: dds_env.py DOMAIN", file=sys.stderr)
        return 2
    domain = int(argv[1])
    print(f"export CYCLONEDDS_URI={shlex.quote(cyclone_uri(domain))}")
    print(f"export ROS_DOMAIN_ID={domain}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
