"""One robot of a team whose world is served by ``ayllu sim serve``, as its own OS process:
the Fig. 2 controller of ``fig2.py`` on an ``ayllu.Node`` on the real clock, over UDP.

    python robot.py ID URL [DURATION] [SEED]

prints ``{"listening": "ADDR"}`` once bound (give that address to the server's and the other
robots' ``peer=``), then ``{"t": ..., "id": ..., "claims": [...]}`` every second, and stops
after DURATION seconds (default: forever) or on SIGTERM / Ctrl-C. Node ids as ``ayllu sim
robot``'s (docs/cli.md): this robot is node ID; its body on the server is node 1000 + ID.
"""

from __future__ import annotations

import json
import signal
import sys
import time

import ayllu
import fig2

TARGETS = 4


def main(argv: list[str]) -> int:
    if len(argv) < 3:
        print(__doc__, file=sys.stderr)
        return 2
    robot_id, url = int(argv[1]), argv[2]
    duration = float(argv[3]) if len(argv) > 3 else float("inf")
    seed = int(argv[4]) if len(argv) > 4 else 1
    node = ayllu.Node(robot_id, url)
    node.install_served_body(TARGETS)
    fig2.build(node, priorities=[float(p) for p in range(TARGETS, 0, -1)], claim_hz=1.0, wander_seed=seed)
    print(json.dumps({"listening": node.address()}), flush=True)
    stop = False

    def on_signal(_sig: int, _frame: object) -> None:
        nonlocal stop
        stop = True

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    node.start()
    end = time.monotonic() + duration
    while not stop and time.monotonic() < end:
        time.sleep(min(1.0, max(0.0, end - time.monotonic())))
        claims = [n for n in range(1, TARGETS + 1) if (s := node.ble_status(f"OBS{n}")) is not None and s.claiming]
        print(json.dumps({"t": round(node.now, 3), "id": robot_id, "claims": claims}), flush=True)
    counts = node.process_error_counts()
    node.close()
    if counts:
        print(json.dumps({"process_errors": {f"{b}.{p}": n for (b, p), n in counts.items()}}), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
