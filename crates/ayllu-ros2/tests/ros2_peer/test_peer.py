#!/usr/bin/env python3
"""Self-test of the ROS 2 test peers (robot.py, peer.py, topics.py) over Cyclone DDS.

What it is for: showing that the peers behave as documented before anything
else relies on them: run `python3 -m pytest crates/ayllu-ros2/tests/ros2_peer`.

What it promises: each DDS test uses its own random ROS domain id in
100..200 and the loopback-only configuration of dds_env.py, so parallel runs
on the machine do not mix and nothing leaves 127.0.0.1; every process it
starts is bounded by its own --duration/--timeout and is ended (by its pid)
when the test ends; the whole module takes about 30 s. Without the `cyclonedds`
package it fails, naming how to install it (`make test-ros2` does): a test
never passes by skipping.
"""

from __future__ import annotations

import json
import math
import os
import queue
import random
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest

from dds_env import cyclone_env, cyclone_uri

try:
    import ros2_types as rt
except ImportError as missing:  # the cyclonedds package is missing
    raise ImportError(
        "the ROS 2 peer needs cyclonedds: make test-ros2 installs it "
        "(pip install -r crates/ayllu-ros2/tests/ros2_peer/requirements.txt)"
    ) from missing

HERE = os.path.dirname(os.path.abspath(__file__))


def script(name: str) -> str:
    return os.path.join(HERE, name)


class Proc:
    """A peer script run in the background, its stdout read line by line."""

    def __init__(self, args: list[str], domain: int) -> None:
        self.popen = subprocess.Popen(
            [sys.executable, args[0], "--domain", str(domain), *args[1:]],
            env=cyclone_env(domain),
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        self.lines: queue.Queue[str | None] = queue.Queue()
        self.seen: list[str] = []
        threading.Thread(target=self._pump, daemon=True).start()

    def _pump(self) -> None:
        assert self.popen.stdout is not None
        for line in self.popen.stdout:
            self.lines.put(line.rstrip("\n"))
        self.lines.put(None)

    def next_json(self, timeout: float) -> dict[str, Any]:
        """The next stdout line as JSON; fails the test after `timeout` s."""
        line = self.lines.get(timeout=timeout)
        if line is None:
            raise AssertionError(f"process ended early: {self.stderr()}")
        self.seen.append(line)
        return json.loads(line)

    def wait_json(self, key: str, timeout: float) -> dict[str, Any]:
        """Skip lines until one with `key`; fails the test after `timeout` s."""
        deadline = time.monotonic() + timeout
        while True:
            obj = self.next_json(max(0.01, deadline - time.monotonic()))
            if key in obj:
                return obj

    def all_json(self, timeout: float) -> list[dict[str, Any]]:
        """Every remaining stdout line as JSON, once the process has ended."""
        self.popen.wait(timeout=timeout)
        out = []
        while True:
            line = self.lines.get(timeout=timeout)
            if line is None:
                return out
            self.seen.append(line)
            out.append(json.loads(line))

    def stderr(self) -> str:
        if self.popen.poll() is None:
            return "(still running)"
        assert self.popen.stderr is not None
        return self.popen.stderr.read()

    def stop(self) -> None:
        if self.popen.poll() is None:
            self.popen.terminate()
            try:
                self.popen.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.popen.kill()
                self.popen.wait(timeout=5)


@pytest.fixture
def domain() -> int:
    return random.SystemRandom().randint(100, 200)


@pytest.fixture
def procs() -> Iterator[list[Proc]]:
    started: list[Proc] = []
    yield started
    for p in started:
        p.stop()


def run(args: list[str], domain: int, timeout: float) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, args[0], "--domain", str(domain), *args[1:]],
        env=cyclone_env(domain),
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )


# ------------------------------------------------------------------ no DDS


def test_dds_names_and_cdr() -> None:
    assert rt.ros_topic_to_dds("/robot1/scan") == "rt/robot1/scan"
    assert rt.dds_topic_to_ros("rt/robot1/scan") == "/robot1/scan"
    assert rt.dds_type_name(rt.LaserScan) == "sensor_msgs::msg::dds_::LaserScan_"
    assert rt.ros_type_name(rt.Odometry) == "nav_msgs/msg/Odometry"
    assert rt.resolve_type("geometry_msgs/msg/Twist") is rt.Twist
    # XCDR1 little endian: encapsulation 00 01 00 00, then the float64.
    assert rt.Float64(1.0).serialize(use_version_2=False).hex() == (
        "00010000" + "000000000000f03f"
    )
    scan = rt.LaserScan(
        header=rt.Header(stamp=rt.Time(1, 2), frame_id="robot1/base_scan"),
        angle_increment=0.5,
        ranges=[1.0, math.inf],
        intensities=[3.0],
    )
    back = rt.LaserScan.deserialize(scan.serialize(use_version_2=False))
    assert back == scan
    assert rt.to_jsonable(scan)["ranges"] == [1.0, "Infinity"]
    assert rt.from_jsonable(rt.LaserScan, rt.to_jsonable(scan)) == scan
    assert len(rt.Odometry().pose.covariance) == 36


def test_cyclone_uri_is_loopback_only() -> None:
    uri = cyclone_uri(150)
    assert '<NetworkInterface name="lo"/>' in uri
    assert "<AllowMulticast>false</AllowMulticast>" in uri
    assert '<Peer address="127.0.0.1"/>' in uri
    assert "<ParticipantIndex>auto</ParticipantIndex>" in uri
    assert cyclone_env(150, base={})["ROS_DOMAIN_ID"] == "150"


def test_robot_geometry() -> None:
    import robot

    world = robot.World(6.0, 4.0, (robot.Box(4.0, 1.0, 5.0, 3.0),))
    assert world.ray(1.0, 2.0, 1.0, 0.0) == pytest.approx(3.0)  # box face x=4
    assert world.ray(1.0, 2.0, -1.0, 0.0) == pytest.approx(1.0)  # wall x=0
    assert world.ray(1.0, 2.0, 0.0, 1.0) == pytest.approx(2.0)  # wall y=4
    assert world.collides(0.1, 2.0)
    assert world.collides(3.9, 2.0)
    assert not world.collides(1.0, 2.0)


# ------------------------------------------------------------------ over DDS


def test_robot_moves_on_cmd_vel(domain: int, procs: list[Proc]) -> None:
    robot_p = Proc([script("robot.py"), "--duration", "6", "--start", "1,2,0"], domain)
    procs.append(robot_p)
    ready = robot_p.wait_json("ready", timeout=10)
    assert ready["topics"]["/robot1/cmd_vel"] == "geometry_msgs/msg/Twist"
    pub = run(
        [
            script("peer.py"),
            "publish",
            "--topic",
            "/robot1/cmd_vel",
            "--type",
            "Twist",
            "--values",
            '{"linear": {"x": 0.3}, "angular": {"z": 0.0}}',
            "--rate",
            "10",
            "--count",
            "25",
            "--wait-match",
            "4",
            "--quiet",
        ],
        domain,
        timeout=20,
    )
    assert pub.returncode == 0, pub.stderr
    pub_lines = [json.loads(x) for x in pub.stdout.splitlines()]
    assert pub_lines[0]["matched"] >= 1
    assert pub_lines[-1] == {"done": True, "cmd": "publish", "sent": 25}
    lines = robot_p.all_json(timeout=15)
    done = lines[-1]
    assert done["done"] is True
    assert robot_p.popen.returncode == 0
    assert done["cmd_received"] >= 20, done
    assert done["cmd_nonzero"] == done["cmd_received"]
    assert done["collisions"] == 0
    assert done["distance"] > 0.4, done  # 25 x 0.1 s at 0.3 m/s = 0.75 m
    assert done["x"] > 1.4 and abs(done["y"] - 2.0) < 0.01, done
    status = [x for x in lines if "cmd" in x]
    assert status and max(s["cmd"]["n"] for s in status) >= 20
    assert any(s["cmd"]["last"] == [0.3, 0.0] for s in status)
    assert done["scans_sent"] >= 50 and done["odom_sent"] >= 100


def test_topics_lists_the_robot(domain: int, procs: list[Proc]) -> None:
    robot_p = Proc([script("robot.py"), "--duration", "8"], domain)
    procs.append(robot_p)
    robot_p.wait_json("ready", timeout=10)
    listed = run([script("topics.py"), "--seconds", "2"], domain, timeout=20)
    assert listed.returncode == 0, listed.stderr
    lines = listed.stdout.splitlines()
    assert "/robot1/scan [sensor_msgs/msg/LaserScan]" in lines
    assert "/robot1/odom [nav_msgs/msg/Odometry]" in lines
    assert "/robot1/cmd_vel [geometry_msgs/msg/Twist]" in lines
    assert lines == sorted(set(lines))
    as_json = run([script("topics.py"), "--seconds", "2", "--json"], domain, 20)
    assert as_json.returncode == 0, as_json.stderr
    topics = json.loads(as_json.stdout)
    scan = topics["/robot1/scan"]
    assert scan["publishers"] == 1 and scan["subscribers"] == 0
    assert scan["qos"][0]["reliability"] == "best_effort"
    assert scan["qos"][0]["durability"] == "volatile"
    assert scan["qos"][0]["depth"] == 5
    cmd = topics["/robot1/cmd_vel"]
    assert cmd["subscribers"] == 1
    assert cmd["qos"][0]["reliability"] == "reliable"
    assert cmd["qos"][0]["depth"] == 10
    assert topics["/robot1/odom"]["qos"][0]["reliability"] == "reliable"


def test_echo_round_trip(domain: int, procs: list[Proc]) -> None:
    values = [1.5, -2.25, 1e300, 0.0, 42.0]
    listener = Proc(
        [
            script("peer.py"),
            "listen",
            "--topic",
            "/pong",
            "--type",
            "Float64",
            "--count",
            str(len(values)),
            "--timeout",
            "15",
        ],
        domain,
    )
    procs.append(listener)
    listener.wait_json("ready", timeout=10)
    echo = Proc(
        [
            script("peer.py"),
            "echo",
            "--in",
            "/ping",
            "--out",
            "/pong",
            "--type",
            "std_msgs/msg/Float64",
            "--count",
            str(len(values)),
            "--timeout",
            "15",
            "--wait-match",
            "5",
        ],
        domain,
    )
    procs.append(echo)
    assert echo.wait_json("ready", timeout=10)["matched"] >= 1
    pub = run(
        [
            script("peer.py"),
            "publish",
            "--topic",
            "/ping",
            "--type",
            "Float64",
            "--values",
            json.dumps([{"data": v} for v in values]),
            "--count",
            str(len(values)),
            "--rate",
            "20",
            "--wait-match",
            "5",
        ],
        domain,
        timeout=20,
    )
    assert pub.returncode == 0, pub.stderr
    got = listener.all_json(timeout=20)
    assert listener.popen.returncode == 0, got
    assert [x["sample"]["data"] for x in got if "sample" in x] == values
    assert echo.all_json(timeout=20)[-1] == {
        "done": True,
        "cmd": "echo",
        "echoed": len(values),
    }


def test_robot_stops_on_sigterm(domain: int, procs: list[Proc]) -> None:
    robot_p = Proc([script("robot.py"), "--duration", "60"], domain)
    procs.append(robot_p)
    robot_p.wait_json("ready", timeout=10)
    t0 = time.monotonic()
    robot_p.popen.terminate()
    done = robot_p.all_json(timeout=10)[-1]
    assert time.monotonic() - t0 < 5
    assert done["done"] is True and done["stopped_by_signal"] is True
    assert robot_p.popen.returncode == 0
