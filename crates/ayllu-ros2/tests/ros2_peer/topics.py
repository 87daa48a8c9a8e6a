#!/usr/bin/env python3
"""List the ROS 2 topics visible on a DDS domain, like `ros2 topic list -t`.

What it is for: checking, without ROS 2 installed, which topics a peer (the
Ayllu ROS 2 body, robot.py, ...) offers or asks for, with which types and QoS.

What it promises: it watches the DDS built-in topics DCPSPublication and
DCPSSubscription for --seconds, then reports the endpoints still alive:

* plain output: one line per ROS 2 topic, sorted, deduplicated, exactly as
  `ros2 topic list -t` prints it: "/robot1/cmd_vel [geometry_msgs/msg/Twist]"
  (only DDS topics with ROS 2's `rt/` prefix, the prefix turned into "/";
  type "pkg::msg::dds_::Type_" rendered "pkg/msg/Type"; several types are
  joined by ", "; topics with a name part starting with "_" are hidden unless
  --include-hidden-topics, as in ROS 2);
* --json: one JSON object {topic: {"types": [...], "publishers": n,
  "subscribers": n, "qos": [{"endpoint", "type", "reliability",
  "durability", "history", "depth", "participant"}, ...], "mismatches":
  [...]}}, where "mismatches" names each writer/reader pair whose QoS keeps
  DDS from matching them (best effort writer for a reliable reader, volatile
  writer for a transient-local reader) or whose types differ. History and
  depth are as the remote endpoint advertises them (DDS does not match on
  them).

It exits by itself after --seconds (default 2); exit status 0.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import sys
import time
from typing import Any

from cyclonedds.builtin import (
    BuiltinDataReader,
    BuiltinTopicDcpsPublication,
    BuiltinTopicDcpsSubscription,
)
from cyclonedds.core import InstanceState, Policy, ReadCondition, SampleState, ViewState
from cyclonedds.domain import DomainParticipant

# Python puts this script's folder first on sys.path: the siblings import as is.
import ros2_types as rt
from dds_env import ensure_loopback

_DURABILITY_RANK = {
    "volatile": 0,
    "transient_local": 1,
    "transient": 2,
    "persistent": 3,
}


def _snake(name: str) -> str:
    return re.sub(r"(?<!^)(?=[A-Z])", "_", name).lower()


def _policy_kind(policy: Any) -> str | None:
    """ "Policy.Reliability.BestEffort" -> "best_effort"."""
    if policy is None:
        return None
    text = str(policy).split("(", 1)[0]
    return _snake(text.rsplit(".", 1)[-1])


def _qos_get(qos: Any, policy: Any) -> Any:
    try:
        return qos[policy]
    except (KeyError, TypeError):
        return None


def describe_qos(qos: Any) -> dict[str, Any]:
    history = _qos_get(qos, Policy.History)
    return {
        "reliability": _policy_kind(_qos_get(qos, Policy.Reliability)),
        "durability": _policy_kind(_qos_get(qos, Policy.Durability)),
        "history": _policy_kind(history),
        "depth": getattr(history, "depth", None),
    }


def is_hidden(topic: str) -> bool:
    return any(part.startswith("_") for part in topic.split("/") if part)


def collect(domain: int, seconds: float) -> dict[str, Any]:
    ensure_loopback(domain)  # before the participant: the DDS library reads it
    dp = DomainParticipant(domain)
    readers = {
        "publisher": BuiltinDataReader(dp, BuiltinTopicDcpsPublication),
        "subscriber": BuiltinDataReader(dp, BuiltinTopicDcpsSubscription),
    }
    stop = {"now": False}

    def on_signal(signum: int, frame: Any) -> None:
        stop["now"] = True

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and not stop["now"]:
        time.sleep(min(0.05, max(0.0, deadline - time.monotonic())))

    topics: dict[str, Any] = {}
    alive = SampleState.Any | ViewState.Any | InstanceState.Alive
    for kind, reader in readers.items():
        seen: set[Any] = set()
        for ep in reader.read(N=10_000, condition=ReadCondition(reader, alive)):
            if ep.key in seen:
                continue
            seen.add(ep.key)
            name = rt.dds_topic_to_ros(ep.topic_name)
            if name is None:
                continue
            entry = topics.setdefault(
                name, {"types": [], "publishers": 0, "subscribers": 0, "qos": []}
            )
            ros_type = rt.ros_type_from_dds(ep.type_name)
            if ros_type not in entry["types"]:
                entry["types"].append(ros_type)
            entry[kind + "s"] += 1
            entry["qos"].append(
                {
                    "endpoint": kind,
                    "type": ros_type,
                    **describe_qos(ep.qos),
                    "participant": str(ep.participant_key),
                }
            )
    for entry in topics.values():
        entry["types"].sort()
        entry["qos"].sort(key=lambda q: (q["endpoint"], q["participant"]))
        entry["mismatches"] = mismatches(entry["qos"])
    return topics


def mismatches(qos: list[dict[str, Any]]) -> list[str]:
    """Writer/reader pairs that DDS will not match, in words."""
    out = []
    writers = [q for q in qos if q["endpoint"] == "publisher"]
    readers = [q for q in qos if q["endpoint"] == "subscriber"]
    for w in writers:
        for r in readers:
            if w["participant"] == r["participant"]:
                continue
            why = []
            if w["type"] != r["type"]:
                why.append(f"type {w['type']} vs {r['type']}")
            if r["reliability"] == "reliable" and w["reliability"] == "best_effort":
                why.append("best_effort writer, reliable reader")
            wd = _DURABILITY_RANK.get(w["durability"] or "", 0)
            rd = _DURABILITY_RANK.get(r["durability"] or "", 0)
            if wd < rd:
                why.append(f"{w['durability']} writer, {r['durability']} reader")
            if why:
                out.append(
                    f"writer {w['participant']} / reader {r['participant']}: "
                    + "; ".join(why)
                )
    return out


def render_plain(topics: dict[str, Any], include_hidden: bool) -> list[str]:
    return [
        f"{name} [{', '.join(entry['types'])}]"
        for name, entry in sorted(topics.items())
        if include_hidden or not is_hidden(name)
    ]


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument(
        "--domain", type=int, default=int(os.environ.get("ROS_DOMAIN_ID", "0"))
    )
    p.add_argument("--seconds", type=float, default=2.0, help="how long to watch")
    p.add_argument("--json", action="store_true", help="JSON with counts and QoS")
    p.add_argument("--include-hidden-topics", action="store_true")
    a = p.parse_args(argv)
    if not 0 < a.seconds <= 3600:
        p.error("--seconds must be in (0, 3600]")
    if not 0 <= a.domain <= 232:
        p.error("--domain must be in [0, 232]")
    topics = collect(a.domain, a.seconds)
    if not a.include_hidden_topics:
        topics = {k: v for k, v in topics.items() if not is_hidden(k)}
    if a.json:
        print(json.dumps(topics, indent=2, sort_keys=True))
    else:
        for line in render_plain(topics, include_hidden=True):
            print(line)
    sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
