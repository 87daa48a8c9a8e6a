#!/usr/bin/env python3
"""A simulated ROS 2 mobile base (unicycle) in a rectangular room with boxes.

What it is for: the other side of the Ayllu ROS 2 body in tests and demos. It
behaves on the wire as a ROS 2 driver on rmw_cyclonedds_cpp would, without ROS 2.

What it promises:

* Publishes `/<ns>/scan` (sensor_msgs/LaserScan, sensor-data QoS, 10 Hz):
  `--beams` beams over 360 degrees, angle_min = 0, counter-clockwise, from the
  robot's centre in its own frame (frame_id "<ns>/base_scan"); a beam with no
  return within range_max is +inf (REP 117); stamp = wall clock.
* Publishes `/<ns>/odom` (nav_msgs/Odometry, default QoS, 20 Hz): frame
  "<ns>/odom", child "<ns>/base_footprint", pose x, y and the yaw quaternion,
  twist = the velocity actually executed, in the child frame.
* Subscribes `/<ns>/cmd_vel` (geometry_msgs/Twist, default QoS): linear.x
  forward m/s, angular.z rad/s counter-clockwise, clamped to --max-linear and
  --max-angular; a command with a non-finite field is counted and ignored;
  with no command for 0.5 s the robot stops (a watchdog, as on real bases).
* Publishes the ROS 2 graph (`ros_discovery_info`, node "<ns>/robot_sim") as
  rmw does, so that ROS 2 tools and ros2-client see a node.
* Physics at 50 Hz. A collision is the robot's disc (radius 0.2 m) overlapping
  a wall or a box: the move into it is not made (rotation still is), and
  `collisions` counts contact onsets (a run of blocked ticks counts once).
* Stdout is JSON lines: one {"ready": true, ...} once every DDS entity exists,
  one status line per second, and a final {"done": true, ...} line. It exits
  by itself after --duration seconds, and on SIGTERM or SIGINT (still
  printing the final line). Exit code 0, or 2 for bad arguments.

Geometry: the room spans [0, W] x [0, H] (metres); an obstacle "x,y,w,h" is the
box [x, x+w] x [y, y+h]; yaw 0 faces +x.
"""

from __future__ import annotations

import argparse
import math
import os
import random
import signal
import sys
import time
from dataclasses import dataclass
from typing import Any

from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

# Python puts this script's folder first on sys.path: the siblings import as is.
import ros2_types as rt
from dds_env import ensure_loopback
from peer_process import Stop, emit

ROBOT_RADIUS = 0.2
PHYSICS_HZ = 50
ODOM_HZ = 20
SCAN_HZ = 10
STATUS_HZ = 1
CMD_TIMEOUT_S = 0.5
RANGE_MIN = 0.12
DEFAULT_OBSTACLES = ["4.0,2.6,0.6,0.6", "1.2,0.4,0.5,0.8", "2.6,3.2,1.0,0.3"]


@dataclass(frozen=True)
class Box:
    x0: float
    y0: float
    x1: float
    y1: float


@dataclass(frozen=True)
class World:
    width: float
    height: float
    boxes: tuple[Box, ...]

    def clearance(self, x: float, y: float) -> float:
        """Distance from the point to the nearest wall or box (negative: inside)."""
        d = min(x, self.width - x, y, self.height - y)
        for b in self.boxes:
            dx = max(b.x0 - x, 0.0, x - b.x1)
            dy = max(b.y0 - y, 0.0, y - b.y1)
            if dx == 0.0 and dy == 0.0:
                d = min(d, -min(x - b.x0, b.x1 - x, y - b.y0, b.y1 - y))
            else:
                d = min(d, math.hypot(dx, dy))
        return d

    def collides(self, x: float, y: float) -> bool:
        return self.clearance(x, y) < ROBOT_RADIUS

    def ray(self, x: float, y: float, c: float, s: float) -> float:
        """Distance along the unit direction (c, s) to the first wall or box."""
        best = math.inf
        if c > 1e-12:
            best = min(best, (self.width - x) / c)
        elif c < -1e-12:
            best = min(best, -x / c)
        if s > 1e-12:
            best = min(best, (self.height - y) / s)
        elif s < -1e-12:
            best = min(best, -y / s)
        for b in self.boxes:
            t = _ray_box(x, y, c, s, b)
            if t is not None and t < best:
                best = t
        return max(best, 0.0)


def _ray_box(x: float, y: float, c: float, s: float, b: Box) -> float | None:
    """Slab test: entry distance of the ray into box b, None if it misses."""
    tmin, tmax = -math.inf, math.inf
    for p, d, lo, hi in ((x, c, b.x0, b.x1), (y, s, b.y0, b.y1)):
        if abs(d) < 1e-12:
            if p < lo or p > hi:
                return None
            continue
        t1, t2 = (lo - p) / d, (hi - p) / d
        if t1 > t2:
            t1, t2 = t2, t1
        tmin, tmax = max(tmin, t1), min(tmax, t2)
        if tmin > tmax:
            return None
    if tmax < 0.0:
        return None
    return max(tmin, 0.0)


def _floats(text: str, n: int, what: str) -> list[float]:
    try:
        parts = [float(v) for v in text.replace("x", ",").split(",")]
    except ValueError:
        parts = []
    if len(parts) != n or not all(math.isfinite(v) for v in parts):
        raise argparse.ArgumentTypeError(f"{what}: expected {n} numbers, got {text!r}")
    return parts


def parse_args(argv: list[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument(
        "--domain", type=int, default=int(os.environ.get("ROS_DOMAIN_ID", "0"))
    )
    p.add_argument("--namespace", default="robot1")
    p.add_argument("--duration", type=float, default=60.0, help="seconds (bounded)")
    p.add_argument("--beams", type=int, default=360)
    p.add_argument("--range-max", type=float, default=5.0)
    p.add_argument("--noise", type=float, default=0.0, help="range noise sigma, m")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--start", default="1.0,2.0,0.0", help="x,y,yaw (m, m, rad)")
    p.add_argument("--room", default="6x4", help="WxH in metres")
    p.add_argument(
        "--obstacle",
        action="append",
        default=None,
        help="x,y,w,h box (repeatable); default: a fixed set of three",
    )
    p.add_argument("--no-obstacles", action="store_true")
    p.add_argument("--max-linear", type=float, default=1.0)
    p.add_argument("--max-angular", type=float, default=3.0)
    a = p.parse_args(argv)
    try:
        a.start_pose = _floats(a.start, 3, "--start")
        a.room_wh = _floats(a.room, 2, "--room")
        specs = [] if a.no_obstacles else (a.obstacle or DEFAULT_OBSTACLES)
        a.boxes = [_floats(o, 4, "--obstacle") for o in specs]
    except argparse.ArgumentTypeError as e:
        p.error(str(e))
    if not 0 < a.duration <= 24 * 3600:
        p.error("--duration must be in (0, 86400]")
    if not 1 <= a.beams <= 100_000:
        p.error("--beams must be in [1, 100000]")
    if a.room_wh[0] <= 2 * ROBOT_RADIUS or a.room_wh[1] <= 2 * ROBOT_RADIUS:
        p.error("--room too small for the robot")
    if any(b[2] <= 0 or b[3] <= 0 for b in a.boxes):
        p.error("--obstacle width and height must be positive")
    return a


class Robot:
    """Unicycle state, command handling and the collision rule."""

    def __init__(self, world: World, x: float, y: float, yaw: float) -> None:
        self.world = world
        self.x, self.y, self.yaw = x, y, _wrap(yaw)
        self.v_cmd = 0.0
        self.w_cmd = 0.0
        self.last_cmd_t = -math.inf
        self.v = 0.0  # executed this tick
        self.w = 0.0
        self.collisions = 0
        self.blocked_ticks = 0
        self.in_contact = False
        self.distance = 0.0
        self.min_clearance = world.clearance(x, y) - ROBOT_RADIUS

    def command(self, v: float, w: float, now: float) -> None:
        self.v_cmd, self.w_cmd, self.last_cmd_t = v, w, now

    def step(self, dt: float, now: float) -> None:
        if now - self.last_cmd_t > CMD_TIMEOUT_S:
            self.v_cmd = self.w_cmd = 0.0
        v, w = self.v_cmd, self.w_cmd
        yaw_mid = self.yaw + 0.5 * w * dt
        nx = self.x + v * math.cos(yaw_mid) * dt
        ny = self.y + v * math.sin(yaw_mid) * dt
        moved = v != 0.0
        blocked = moved and self.world.collides(nx, ny)
        if blocked:
            self.blocked_ticks += 1
            if not self.in_contact:
                self.collisions += 1
            self.in_contact = True
            self.v = 0.0
        else:
            self.in_contact = False
            if moved:
                self.distance += math.hypot(nx - self.x, ny - self.y)
                self.x, self.y = nx, ny
            self.v = v
        self.yaw = _wrap(self.yaw + w * dt)
        self.w = w
        self.min_clearance = min(
            self.min_clearance, self.world.clearance(self.x, self.y) - ROBOT_RADIUS
        )


def _due(tick: int, hz: int) -> bool:
    """True on the physics ticks where a `hz` publisher fires (hz per second)."""
    return (tick * hz) // PHYSICS_HZ != ((tick - 1) * hz) // PHYSICS_HZ


def _wrap(a: float) -> float:
    return math.atan2(math.sin(a), math.cos(a))


def _r(v: float, n: int = 4) -> float:
    return round(v, n)


def run(a: argparse.Namespace) -> int:
    ensure_loopback(a.domain)  # before the participant: the DDS library reads it
    w_, h_ = a.room_wh
    world = World(w_, h_, tuple(Box(x, y, x + bw, y + bh) for x, y, bw, bh in a.boxes))
    sx, sy, syaw = a.start_pose
    if world.collides(sx, sy):
        print(f"start pose {a.start} collides with the room", file=sys.stderr)
        return 2
    robot = Robot(world, sx, sy, syaw)
    rng = random.Random(a.seed)

    ns = a.namespace.strip("/")
    prefix = f"/{ns}" if ns else ""
    frame = f"{ns}/" if ns else ""
    dp = DomainParticipant(a.domain)
    scan_topic = Topic(dp, rt.ros_topic_to_dds(f"{prefix}/scan"), rt.LaserScan)
    odom_topic = Topic(dp, rt.ros_topic_to_dds(f"{prefix}/odom"), rt.Odometry)
    cmd_topic = Topic(dp, rt.ros_topic_to_dds(f"{prefix}/cmd_vel"), rt.Twist)
    scan_w = DataWriter(dp, scan_topic, rt.qos_sensor_data())
    odom_w = DataWriter(dp, odom_topic, rt.qos_default())
    cmd_r = DataReader(dp, cmd_topic, rt.qos_default())
    graph_topic = Topic(dp, rt.ROS_DISCOVERY_TOPIC, rt.ParticipantEntitiesInfo)
    graph_w = DataWriter(dp, graph_topic, rt.qos_discovery_info())
    node = rt.NodeEntitiesInfo(
        node_namespace=prefix or "/",
        node_name="robot_sim",
        reader_gid_seq=[_gid(cmd_r)],
        writer_gid_seq=[_gid(scan_w), _gid(odom_w), _gid(graph_w)],
    )
    graph_w.write(
        rt.ParticipantEntitiesInfo(gid=_gid(dp), node_entities_info_seq=[node])
    )

    stop = Stop()
    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)

    n = a.beams
    inc = 2.0 * math.pi / n
    scan_time = 1.0 / SCAN_HZ
    beam_dirs = [(math.cos(i * inc), math.sin(i * inc)) for i in range(n)]
    cmd_n = cmd_nonzero = cmd_invalid = 0
    last_cmd = [0.0, 0.0]
    scans = odoms = 0
    emit(
        {
            "ready": True,
            "domain": a.domain,
            "namespace": prefix or "/",
            "topics": {
                f"{prefix}/scan": "sensor_msgs/msg/LaserScan",
                f"{prefix}/odom": "nav_msgs/msg/Odometry",
                f"{prefix}/cmd_vel": "geometry_msgs/msg/Twist",
            },
            "room": [w_, h_],
            "obstacles": [list(b) for b in a.boxes],
            "pose": [_r(robot.x), _r(robot.y), _r(robot.yaw)],
            "beams": n,
            "range_max": a.range_max,
            "pid": os.getpid(),
        }
    )

    dt = 1.0 / PHYSICS_HZ
    t0 = time.monotonic()
    total_ticks = round(a.duration * PHYSICS_HZ)
    tick = 0
    while tick < total_ticks and not stop.requested:
        now = t0 + tick * dt
        delay = now - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        mono = time.monotonic()
        for s in rt.take_valid(cmd_r):
            cmd_n += 1
            lin, ang = s.linear.x, s.angular.z
            last_cmd = [lin, ang]
            if not (math.isfinite(lin) and math.isfinite(ang)):
                cmd_invalid += 1
                continue
            if lin != 0.0 or ang != 0.0:
                cmd_nonzero += 1
            v = max(-a.max_linear, min(a.max_linear, lin))
            w = max(-a.max_angular, min(a.max_angular, ang))
            robot.command(v, w, mono)
        robot.step(dt, mono)
        tick += 1
        wall = time.time_ns()
        if _due(tick, ODOM_HZ):
            odom_w.write(_odometry(robot, frame, wall))
            odoms += 1
        if _due(tick, SCAN_HZ):
            ranges = []
            cy, sy_ = math.cos(robot.yaw), math.sin(robot.yaw)
            for bc, bs in beam_dirs:
                c = cy * bc - sy_ * bs
                s_ = sy_ * bc + cy * bs
                d = world.ray(robot.x, robot.y, c, s_)
                if a.noise > 0.0:
                    d += rng.gauss(0.0, a.noise)
                if d > a.range_max:
                    d = math.inf
                elif d < RANGE_MIN:
                    d = -math.inf
                ranges.append(d)
            scan_w.write(
                rt.LaserScan(
                    header=rt.Header(
                        stamp=rt.stamp_now(wall), frame_id=f"{frame}base_scan"
                    ),
                    angle_min=0.0,
                    angle_max=(n - 1) * inc,
                    angle_increment=inc,
                    time_increment=scan_time / n,
                    scan_time=scan_time,
                    range_min=RANGE_MIN,
                    range_max=a.range_max,
                    ranges=ranges,
                    intensities=[100.0 if math.isfinite(r) else 0.0 for r in ranges],
                )
            )
            scans += 1
        if _due(tick, STATUS_HZ):
            emit(
                {
                    "t": _r(tick * dt, 2),
                    "x": _r(robot.x),
                    "y": _r(robot.y),
                    "yaw": _r(robot.yaw),
                    "cmd": {"n": cmd_n, "last": [_jf(v) for v in last_cmd]},
                    "collisions": robot.collisions,
                    "distance": _r(robot.distance),
                }
            )
    emit(
        {
            "done": True,
            "t": _r(tick * dt, 2),
            "stopped_by_signal": stop.requested,
            "x": _r(robot.x),
            "y": _r(robot.y),
            "yaw": _r(robot.yaw),
            "collisions": robot.collisions,
            "blocked_ticks": robot.blocked_ticks,
            "distance": _r(robot.distance),
            "cmd_received": cmd_n,
            "cmd_nonzero": cmd_nonzero,
            "cmd_invalid": cmd_invalid,
            "min_clearance": _r(robot.min_clearance),
            "scans_sent": scans,
            "odom_sent": odoms,
        }
    )
    return 0


def _jf(v: float) -> float | str:
    """A float for strict JSON: non-finite values as strings."""
    if math.isnan(v):
        return "NaN"
    if math.isinf(v):
        return "Infinity" if v > 0 else "-Infinity"
    return _r(v)


def _gid(entity: Any) -> rt.Gid:
    """The rmw GID of a DDS entity: its 16-byte GUID."""
    return rt.Gid(data=list(entity.guid.bytes))


def _odometry(robot: Robot, frame: str, wall_ns: int) -> rt.Odometry:
    cov_pose = [0.0] * 36
    cov_twist = [0.0] * 36
    for i, v in enumerate((1e-3, 1e-3, 1e6, 1e6, 1e6, 1e-3)):
        cov_pose[i * 7] = v
        cov_twist[i * 7] = v
    return rt.Odometry(
        header=rt.Header(stamp=rt.stamp_now(wall_ns), frame_id=f"{frame}odom"),
        child_frame_id=f"{frame}base_footprint",
        pose=rt.PoseWithCovariance(
            pose=rt.Pose(
                position=rt.Point(robot.x, robot.y, 0.0),
                orientation=rt.yaw_to_quaternion(robot.yaw),
            ),
            covariance=cov_pose,
        ),
        twist=rt.TwistWithCovariance(
            twist=rt.Twist(
                linear=rt.Vector3(robot.v, 0.0, 0.0),
                angular=rt.Vector3(0.0, 0.0, robot.w),
            ),
            covariance=cov_twist,
        ),
    )


def main(argv: list[str]) -> int:
    return run(parse_args(argv))


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
