"""Tutorial 8, two machines, one program per robot (docs/tutorials/08-two-machines.md), in
Python: the same program runs on every robot, told only its id (1 or 2). Each robot's sonar
drives the motor of the other robot across the network, and each prints what its own motor
receives, from whom, then `why`. The nodes find each other from `AYLLU_URL` (the subnet form
on robots; with it unset, the machine-local default), on the real clock.

Run, on machine A and machine B of one subnet:

    export AYLLU_URL='udp://0.0.0.0:0?discovery=239.255.65.89:7390&ttl=1'
    python3 main.py 1    # on A
    python3 main.py 2    # on B

Exits 0 once the other robot's values have driven this robot's motor, 1 (naming the likely
cause) if none arrived within the run (`--for SECONDS`, 10 by default). The Rust program beside
it is the same robot: a Python robot and a Rust robot make a team.
"""

import argparse
import sys
import time

import ayllu


def partner(robot: int) -> int:
    """The other robot of the two: whose motor this robot's sonar drives, and whose sonar drives
    this robot's motor."""
    return 3 - robot


def make_sonar(reading: float) -> type:
    """A sonar class writing `reading` at 20 Hz: a distinct constant per robot, so each motor's
    value says which robot it came from."""

    class Sonar(ayllu.Behavior):
        range = ayllu.Port(0.0, name="Range")

        @ayllu.every(hz=20)
        def ping(self, ctx: ayllu.Context) -> None:
            ctx.write(self.range, reading)

    return Sonar


class Motor(ayllu.Behavior):
    # Stale 300 ms after its last command (rule S4): a robot that loses its partner sees it at once.
    speed = ayllu.Port(0.0, name="Speed", lifespan=0.3)


def run(robot: int, seconds: float) -> bool:
    """Robot `robot` for `seconds` of the real clock, printing as it goes; True once the other
    robot's values drove this motor."""
    other = partner(robot)
    node = ayllu.Node(robot, ayllu.default_url())  # AYLLU_URL, else the machine-local default
    node.create(make_sonar(0.5 + 0.1 * robot), "SONAR")
    node.create(Motor, "MOTOR")
    # A connection to a port of another robot, by node id: no address.
    node.connect(ayllu.local("SONAR", "Range"), ayllu.remote(other, "MOTOR", "Speed"))
    print(f"robot {robot} at {node.address()}, its sonar drives robot {other}'s motor", flush=True)
    node.start()  # the node runs on a background thread
    start, received = time.monotonic(), 0
    for second in range(1, int(seconds) + 1):
        time.sleep(max(0.0, start + second - time.monotonic()))
        why = node.why("MOTOR", "Speed")
        supplier = why.supplier
        by = f"n{supplier.node}/c{supplier.conn}" if supplier is not None else "nobody"
        value = f"{why.value:.1f}" if why.fresh else "stale"
        print(f"{time.monotonic() - start:4.1f} s  MOTOR.Speed = {value} from {by}", flush=True)
        if why.fresh and supplier is not None and supplier.node == other:
            received += 1
    why = node.why("MOTOR", "Speed")
    node.close()
    if received == 0:
        print(
            f"nothing from robot {other} in {seconds} s: is it running, with the same AYLLU_URL "
            "(ttl=1 across machines, the same team= and key=)? docs/troubleshooting.md, by symptom",
            file=sys.stderr,
        )
        return False
    print(why)
    return True


def main() -> None:
    parser = argparse.ArgumentParser(description="One robot of tutorial 8's team of two.")
    parser.add_argument("id", type=int, choices=[1, 2], help="this robot's node id")
    parser.add_argument("--for", dest="seconds", type=float, default=10.0, help="seconds to run")
    args = parser.parse_args()
    sys.exit(0 if run(args.id, args.seconds) else 1)


if __name__ == "__main__":
    main()
