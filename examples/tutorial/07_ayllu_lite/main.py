"""Tutorial 7, joining a team from a microcontroller with AylluLite
(docs/tutorials/07-ayllu-lite.md): a small board that is not an Ayllu node (here the one-file
Python client, lite/python/ayllu_lite.py; the C client lite/c is the same protocol without
malloc) joins a robot's team over UDP. It exposes a port the robot writes (a status LED) and
writes the robot's motor with an override, as a remote control would.

Run: `python main.py [UDP_CLIENT]` with the `ayllu` package installed; UDP_CLIENT is the host
build of lite/c's example (`make -C lite/c`), standing in for the microcontroller's C firmware.
Exits non-zero if what the tutorial says does not happen.
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import ayllu

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "lite" / "python"))
import ayllu_lite  # the one file a board copies

LOOP = ("127.0.0.1", 0)


class Motor(ayllu.Behavior):
    speed = ayllu.Port(0.0, name="Speed", lifespan=1.0)


class Status(ayllu.Behavior):
    led = ayllu.Port(0, name="Led")

    @ayllu.every(hz=20)
    def blink(self, ctx: ayllu.Context) -> None:
        ctx.write(self.led, 1)


def wait(condition: Callable[[], object], seconds: float = 10.0) -> bool:
    deadline = time.monotonic() + seconds  # bounded
    while not condition() and time.monotonic() < deadline:
        time.sleep(0.01)
    return bool(condition())


def main(udp_client: str | None) -> None:
    robot = ayllu.Node(1, "udp://127.0.0.1:0")
    robot.create(Motor, "MOTOR")
    robot.create(Status, "STATUS")
    address = robot.address()  # None only for nodes without a socket (mem://)
    assert address is not None
    host, port = address.rsplit(":", 1)

    # The board: node id 50, told where the robot is; it greets the robot with HELLO.
    board = ayllu_lite.LiteNode(50, bind=LOOP, peers=[(1, (host, int(port)))], hello_interval_ms=100)
    board.expose("BOARD", "Led", 0)
    robot.connect(ayllu.local("STATUS", "Led"), ayllu.remote(50, "BOARD", "Led"))  # robot -> board
    robot.start()
    board.start()
    try:
        assert wait(lambda: board.get("BOARD", "Led") == 1), "the robot wrote the board's port"
        print("board's BOARD.Led =", board.get("BOARD", "Led"))

        # The board takes the motor over for 0.5 s, as a hand-held remote would.
        board.write(1, "MOTOR", "Speed", 0.4, kind=ayllu_lite.ConnKind.OVERRIDE_IN, period_s=0.5)
        assert wait(lambda: robot.read("MOTOR", "Speed") == 0.4), "the board wrote the robot's motor"
        why = robot.why("MOTOR", "Speed")
        print(f"robot's MOTOR.Speed = {why.value}, supplied by node {why.supplier.node}")
        assert why.supplier.node == 50
        print("board reads it back:", board.read(1, "MOTOR", "Speed"))

        # While the board's window is open, only the board may write the motor; it closes 0.5 s
        # after the board's last value.
        assert wait(lambda: robot.why("MOTOR", "Speed").input_blocked is None), "the override ended"
        if udp_client:  # the C client, built for the host, writes the motor (a Normal write)
            cmd = [udp_client, "--node", "51", host, port, "MOTOR", "Speed", "0.25"]
            subprocess.run(cmd, check=True, timeout=30)
            assert wait(lambda: robot.read("MOTOR", "Speed") == 0.25), "the C client wrote the motor"
            print(f"after {Path(udp_client).name}: MOTOR.Speed = {robot.read('MOTOR', 'Speed')}")
    finally:
        board.close()
        robot.close()


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
