"""Tutorial 6, recording a team and asking `why` in the past
(docs/tutorials/06-recording-why-in-the-past.md), in Python: two robots share a task by BLE,
each node a flight recorder; robot 1 (the more eligible) dies at 3 s and robot 2 takes over.
The recordings are then asked questions with `ayllu replay` (replay.sh beside this file).

Run: `python main.py DIR`; writes DIR/n1.mcap and DIR/n2.mcap. Exits non-zero if what the
tutorial says does not happen.
"""

import sys
from pathlib import Path

import ayllu

ELIGIBILITY = {1: 0.9, 2: 0.5}  # how well suited each robot is


class Worker(ayllu.Behavior):
    out = ayllu.Port(0.0, name="Out")

    @ayllu.every(hz=10)
    def work(self, ctx: ayllu.Context) -> None:
        ctx.write(self.LOCAL, ELIGIBILITY[ctx.node])
        ctx.write(self.out, 1.0)  # doing the task


def claiming(robot: ayllu.Node) -> bool:
    status = robot.ble_status("W")  # None for a behavior in no BLE group
    return status is not None and bool(status.claiming)


def main(out: Path) -> None:
    team = ayllu.Team()
    robots = [team.add(1), team.add(2)]
    for robot in robots:
        robot.record(out / f"n{robot.id}.mcap")  # first: a replay rebuilds from the first definition
        robot.create(Worker, "W")
        robot.ble_join("W", "Peers", "Out", 1.0)
    team.advance(3.0, tick=0.01)
    assert [claiming(r) for r in robots] == [True, False], "robot 1 claims the task"
    robots[0].stop_recording()
    team.kill(1)  # robot 1 dies
    team.advance(5.0, tick=0.01)
    assert claiming(robots[1]), "robot 2 took the task over"
    robots[1].stop_recording()
    for robot in robots:
        values = ayllu.check_recording(out / f"n{robot.id}.mcap")  # replayed bit for bit
        print(f"n{robot.id}.mcap: {values} accepted values replay bit for bit")
        assert values > 0


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "."))
