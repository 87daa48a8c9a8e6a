#!/usr/bin/env python3
"""A small multi-purpose ROS 2 peer (Cyclone DDS) for tests and benchmarks.

What it is for: to talk to the Ayllu ROS 2 body as any ROS 2 node would, and
to misbehave on purpose, without ROS 2 installed.

Subcommands (topics are ROS 2 names, "/robot1/cmd_vel"; types are "Float64",
"std_msgs/msg/Float64" or the DDS name):

  echo     --in T --out T --type NAME [--qos ...] --count N --timeout S
           republish every sample received on --in to --out unchanged (a
           DDS-only round-trip partner); --wait-match S first waits up to S
           seconds for a reader of --out.
  publish  --topic T --type NAME --values JSON --rate HZ --count N
           publish N samples; JSON is a field dict (nested, partial: missing
           fields are zero) or a list of them, used in turn. --wait-match S
           first waits up to S seconds for a reader (a ROS 2 node would not).
  listen   --topic T --type NAME --count N --timeout S
           print each received sample as a JSON line.
  bad      --topic T --kind wrong_type|truncated|huge|nan --count N [--type]
           misbehave: `wrong_type` publishes std_msgs/String on the topic (a
           DDS reader of another type does not match it: expected);
           `truncated` publishes a shorter struct under the target's own DDS
           type name (Float64, Twist, LaserScan, Odometry), so a decoder that
           trusts the name runs out of bytes; `huge` publishes LaserScans of
           10^6 ranges (about 4 MB each); `nan` publishes NaN (Float64/Float32
           data, Twist linear.x, or every float field of other types).

What it promises: JSON lines on stdout: {"ready": true, ...} once its DDS
entities exist, one line per sample sent or received (echo: only with
--verbose), and a last {"done": true, ...} line. Every loop is bounded by
--count and --timeout (or --count / --rate); SIGTERM and SIGINT end it early,
still printing the last line. Exit status: 0 when --count was reached, 3 when
the timeout came first, 2 for bad arguments. Non-finite floats are printed as
the strings "NaN", "Infinity", "-Infinity" (strict JSON); --values accepts
those strings as well as JSON's NaN/Infinity literals.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import sys
import time
from typing import Any

from cyclonedds.core import (
    DDSException,
    InstanceState,
    ReadCondition,
    SampleState,
    ViewState,
    WaitSet,
)
from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

# Python puts this script's folder first on sys.path: the siblings import as is.
import ros2_types as rt
from dds_env import ensure_loopback
from peer_process import Stop, emit

EXIT_OK = 0
EXIT_USAGE = 2
EXIT_TIMEOUT = 3
HUGE_RANGES = 1_000_000
SENSOR_TYPES = (rt.LaserScan, rt.Range)


STOP = Stop()


def qos_for(name: str, cls: type) -> Any:
    if name == "auto":
        name = "sensor_data" if cls in SENSOR_TYPES else "default"
    return rt.qos_profile(name)


def wait_for_match(entity: Any, seconds: float, writer: bool) -> int:
    """Wait up to `seconds` for a matched remote endpoint; the number matched."""
    deadline = time.monotonic() + seconds
    while True:
        if writer:
            n = len(entity.get_matched_subscriptions())
        else:
            n = len(entity.get_matched_publications())
        if n > 0 or time.monotonic() >= deadline or STOP.requested:
            return n
        time.sleep(0.02)


def _participant(domain: int) -> DomainParticipant:
    ensure_loopback(domain)  # before the participant: the DDS library reads it
    return DomainParticipant(domain)


def _reader_waitset(reader: DataReader) -> WaitSet:
    ws = WaitSet(reader.participant)
    ws.attach(
        ReadCondition(reader, SampleState.NotRead | ViewState.Any | InstanceState.Any)
    )
    return ws


def _remaining(deadline: float) -> float:
    return max(0.0, deadline - time.monotonic())


def cmd_echo(a: argparse.Namespace) -> int:
    cls = rt.resolve_type(a.type)
    qos = qos_for(a.qos, cls)
    dp = _participant(a.domain)
    reader = DataReader(dp, Topic(dp, rt.ros_topic_to_dds(a.in_topic), cls), qos)
    writer = DataWriter(dp, Topic(dp, rt.ros_topic_to_dds(a.out_topic), cls), qos)
    ws = _reader_waitset(reader)
    matched = wait_for_match(writer, a.wait_match, writer=True)
    emit(
        {
            "ready": True,
            "cmd": "echo",
            "in": a.in_topic,
            "out": a.out_topic,
            "matched": matched,
        }
    )
    echoed = 0
    deadline = time.monotonic() + a.timeout
    while echoed < a.count and not STOP.requested:
        left = _remaining(deadline)
        if left <= 0.0:
            break
        ws.wait(duration(seconds=min(left, 0.2)))
        for s in rt.take_valid(reader, 256):
            writer.write(s)
            echoed += 1
            if a.verbose:
                emit({"echoed": echoed, "sample": rt.to_jsonable(s)})
            if echoed >= a.count:
                break
    emit({"done": True, "cmd": "echo", "echoed": echoed})
    return EXIT_OK if echoed >= a.count else EXIT_TIMEOUT


def _parse_values(cls: type, text: str) -> list[Any]:
    try:
        raw = json.loads(text)
    except json.JSONDecodeError as e:
        raise ValueError(f"--values is not JSON: {e}") from None
    items = raw if isinstance(raw, list) else [raw]
    if not items:
        raise ValueError("--values: empty list")
    return [rt.from_jsonable(cls, item) for item in items]


def _paced(count: int, rate: float) -> Any:
    """Yield 0..count-1 at `rate` Hz (no pacing for rate <= 0); stops on signal."""
    period = 1.0 / rate if rate > 0 else 0.0
    t0 = time.monotonic()
    for i in range(count):
        if STOP.requested:
            return
        delay = t0 + i * period - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        yield i


def cmd_publish(a: argparse.Namespace) -> int:
    cls = rt.resolve_type(a.type)
    samples = _parse_values(cls, a.values)
    dp = _participant(a.domain)
    writer = DataWriter(
        dp, Topic(dp, rt.ros_topic_to_dds(a.topic), cls), qos_for(a.qos, cls)
    )
    matched = wait_for_match(writer, a.wait_match, writer=True)
    emit({"ready": True, "cmd": "publish", "topic": a.topic, "matched": matched})
    sent = 0
    for i in _paced(a.count, a.rate):
        s = samples[i % len(samples)]
        writer.write(s)
        sent += 1
        if not a.quiet:
            emit({"sent": sent, "sample": rt.to_jsonable(s)})
    _linger(writer, a.linger)
    emit({"done": True, "cmd": "publish", "sent": sent})
    return EXIT_OK


def _linger(writer: DataWriter, seconds: float) -> None:
    """Give reliable readers time to receive (and NACK) the last samples."""
    if seconds <= 0:
        return
    try:
        writer.wait_for_acks(duration(seconds=seconds))
    except DDSException:  # e.g. best effort: nothing to wait for, so just pause
        time.sleep(min(seconds, 0.2))


def cmd_listen(a: argparse.Namespace) -> int:
    cls = rt.resolve_type(a.type)
    dp = _participant(a.domain)
    reader = DataReader(
        dp, Topic(dp, rt.ros_topic_to_dds(a.topic), cls), qos_for(a.qos, cls)
    )
    ws = _reader_waitset(reader)
    emit({"ready": True, "cmd": "listen", "topic": a.topic})
    got = 0
    deadline = time.monotonic() + a.timeout
    while got < a.count and not STOP.requested:
        left = _remaining(deadline)
        if left <= 0.0:
            break
        ws.wait(duration(seconds=min(left, 0.2)))
        for s in rt.take_valid(reader, 256):
            got += 1
            emit({"n": got, "sample": rt.to_jsonable(s)})
            if got >= a.count:
                break
    emit({"done": True, "cmd": "listen", "received": got})
    return EXIT_OK if got >= a.count else EXIT_TIMEOUT


def _nan_sample(cls: type) -> Any:
    if cls is rt.Twist:
        return rt.Twist(linear=rt.Vector3(x=math.nan))
    return _all_floats_nan(cls())


def _all_floats_nan(obj: Any) -> Any:
    """Set every float field (recursively, sequences too) of a sample to NaN."""
    as_json = rt.to_jsonable(obj)

    def nanify(v: Any) -> Any:
        if isinstance(v, dict):
            return {k: nanify(x) for k, x in v.items()}
        if isinstance(v, list):
            return [nanify(x) for x in v]
        if isinstance(v, float):
            return "NaN"
        return v

    return rt.from_jsonable(type(obj), nanify(as_json))


def _huge_scan(seq: int) -> rt.LaserScan:
    n = HUGE_RANGES
    inc = 2.0 * math.pi / n
    return rt.LaserScan(
        header=rt.Header(stamp=rt.stamp_now(time.time_ns()), frame_id="huge"),
        angle_min=0.0,
        angle_max=(n - 1) * inc,
        angle_increment=inc,
        time_increment=0.0,
        scan_time=0.1,
        range_min=0.1,
        range_max=10.0,
        ranges=[1.0 + (seq % 7) * 0.1] * n,
        intensities=[],
    )


def cmd_bad(a: argparse.Namespace) -> int:
    target = rt.resolve_type(a.type)
    if a.kind == "wrong_type":
        cls: type = rt.String
    elif a.kind == "truncated":
        if target not in rt.TRUNCATED:
            names = sorted(c.__name__ for c in rt.TRUNCATED)
            print(f"truncated: --type must be one of {names}", file=sys.stderr)
            return EXIT_USAGE
        cls = rt.TRUNCATED[target]
    elif a.kind == "huge":
        cls = rt.LaserScan
    else:
        cls = target
    dp = _participant(a.domain)
    qos_cls = rt.LaserScan if a.kind == "huge" else target
    writer = DataWriter(
        dp, Topic(dp, rt.ros_topic_to_dds(a.topic), cls), qos_for(a.qos, qos_cls)
    )
    matched = wait_for_match(writer, a.wait_match, writer=True)
    emit(
        {
            "ready": True,
            "cmd": "bad",
            "kind": a.kind,
            "topic": a.topic,
            "dds_type": rt.dds_type_name(cls),
            "matched": matched,
        }
    )
    sent = 0
    for i in _paced(a.count, a.rate):
        if a.kind == "wrong_type":
            s: Any = rt.String(data=f"not a {target.__name__} #{i}")
            shown: Any = rt.to_jsonable(s)
        elif a.kind == "truncated":
            s = cls()
            shown = rt.to_jsonable(s)
        elif a.kind == "huge":
            s = _huge_scan(i)
            shown = {"ranges_len": len(s.ranges), "frame_id": s.header.frame_id}
        else:
            s = _nan_sample(target)
            shown = rt.to_jsonable(s)
        payload = s.serialize(use_version_2=False)
        writer.write(s)
        sent += 1
        emit(
            {
                "sent": sent,
                "kind": a.kind,
                "dds_type": rt.dds_type_name(cls),
                "bytes": len(payload),
                "sample": shown,
            }
        )
    _linger(writer, a.linger)
    emit({"done": True, "cmd": "bad", "kind": a.kind, "sent": sent})
    return EXIT_OK


def _positive_int(text: str) -> int:
    v = int(text)
    if not 1 <= v <= 10_000_000:
        raise argparse.ArgumentTypeError("must be in [1, 10000000]")
    return v


def _timeout(text: str) -> float:
    v = float(text)
    if not 0 < v <= 24 * 3600:
        raise argparse.ArgumentTypeError("must be in (0, 86400]")
    return v


def parse_args(argv: list[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument(
        "--domain", type=int, default=int(os.environ.get("ROS_DOMAIN_ID", "0"))
    )
    sub = p.add_subparsers(dest="cmd", required=True)
    qos_choices = ["auto", "default", "sensor_data"]
    qos_help = "QoS profile; auto: sensor_data for LaserScan/Range, else default"

    e = sub.add_parser("echo", help="republish --in on --out")
    e.add_argument("--in", dest="in_topic", required=True)
    e.add_argument("--out", dest="out_topic", required=True)
    e.add_argument("--type", default="Float64")
    e.add_argument("--qos", choices=qos_choices, default="auto", help=qos_help)
    e.add_argument("--count", type=_positive_int, default=100)
    e.add_argument("--timeout", type=_timeout, default=30.0)
    e.add_argument("--verbose", action="store_true", help="print each sample")
    e.add_argument(
        "--wait-match", type=float, default=0.0, help="seconds to wait for --out"
    )

    pub = sub.add_parser("publish", help="publish samples given as JSON")
    pub.add_argument("--topic", required=True)
    pub.add_argument("--type", required=True)
    pub.add_argument("--values", default="{}", help="JSON field dict or list")
    pub.add_argument("--rate", type=float, default=10.0, help="Hz; <= 0: no pause")
    pub.add_argument("--count", type=_positive_int, default=10)
    pub.add_argument("--qos", choices=qos_choices, default="auto", help=qos_help)
    pub.add_argument("--wait-match", type=float, default=0.0, help="seconds")
    pub.add_argument("--linger", type=float, default=0.5, help="seconds")
    pub.add_argument("--quiet", action="store_true", help="no line per sample")

    li = sub.add_parser("listen", help="print received samples")
    li.add_argument("--topic", required=True)
    li.add_argument("--type", required=True)
    li.add_argument("--qos", choices=qos_choices, default="auto", help=qos_help)
    li.add_argument("--count", type=_positive_int, default=10)
    li.add_argument("--timeout", type=_timeout, default=30.0)

    b = sub.add_parser("bad", help="misbehaving publisher")
    b.add_argument("--topic", required=True)
    b.add_argument(
        "--kind", required=True, choices=["wrong_type", "truncated", "huge", "nan"]
    )
    b.add_argument("--type", default="Float64", help="the type the topic should have")
    b.add_argument("--count", type=_positive_int, default=5)
    b.add_argument("--rate", type=float, default=5.0, help="Hz; <= 0: no pause")
    b.add_argument("--qos", choices=qos_choices, default="auto", help=qos_help)
    b.add_argument("--wait-match", type=float, default=0.0, help="seconds")
    b.add_argument("--linger", type=float, default=0.5, help="seconds")
    a = p.parse_args(argv)
    for name in ("wait_match", "linger"):
        if not 0 <= getattr(a, name, 0.0) <= 3600:
            p.error(f"--{name.replace('_', '-')} must be in [0, 3600]")
    if not 0 <= a.domain <= 232:
        p.error("--domain must be in [0, 232]")
    return a


def main(argv: list[str]) -> int:
    a = parse_args(argv)
    signal.signal(signal.SIGTERM, STOP)
    signal.signal(signal.SIGINT, STOP)
    handlers = {
        "echo": cmd_echo,
        "publish": cmd_publish,
        "listen": cmd_listen,
        "bad": cmd_bad,
    }
    try:
        return handlers[a.cmd](a)
    except (ValueError, TypeError) as e:
        print(f"peer.py {a.cmd}: {e}", file=sys.stderr)
        return EXIT_USAGE


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
