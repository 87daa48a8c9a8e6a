"""The concepts page's code (docs/concepts.md), in Python: each section between the --8<--
markers is shown on that page beside the same in Rust and C; this program runs them all and
checks what the page says (an AssertionError otherwise).
"""

import ayllu


# --8<-- [start:behavior]
class Observer(ayllu.Behavior):
    """A behavior class: its registers (ports, slots, monostables) and its processes."""

    target_x = ayllu.Port(0.0, name="TargetX", lifespan=0.25)  # a port, typed by its default
    rotate = ayllu.Port(0.0, name="Rotate")
    seen = ayllu.Slot(0, name="Seen")  # a slot: internal state, never connectable
    tracking = ayllu.Monostable(name="Tracking")  # true for a while after each trigger

    @ayllu.on_write(target_x)  # runs whenever TargetX accepts a value
    def saw(self, ctx: ayllu.Context) -> None:
        ctx.trigger(self.tracking, 1.0)
        ctx.set_slot(self.seen, ctx.slot(self.seen) + 1)

    @ayllu.every(hz=20)  # 20 times a second
    def turn(self, ctx: ayllu.Context) -> None:
        x = ctx.get(self.target_x)  # None when stale: rule S4
        ctx.write(self.rotate, -0.5 * x if x is not None and ctx.is_high(self.tracking) else 0.0)


# --8<-- [end:behavior]


def behaviors_and_processes() -> None:
    node = ayllu.Node(1, manual=True)
    # --8<-- [start:instance]
    node.create(Observer, "OBS1")  # a behavior: an instance of the class
    node.write("OBS1", "TargetX", 0.4)  # as a camera would
    node.step()  # Saw runs, then Turn
    assert node.read("OBS1", "Rotate") == -0.2
    # --8<-- [end:instance]
    assert node.monostable("OBS1", "Tracking")
    node.set_time(0.3)
    assert node.read("OBS1", "Rotate") == 0.0, "TargetX went stale after 250 ms"


class Cmd(ayllu.Behavior):
    out = ayllu.Port(0.0, name="Out")


def connections() -> None:
    node = ayllu.Node(1, manual=True)
    for name in "ABCDEFG":
        node.create(Cmd, name)
    g = ayllu.local("G", "Out")
    # --8<-- [start:connections]
    p = 0.5  # the window's period, in seconds
    node.connect(ayllu.local("A", "Out"), g)  # Normal
    node.connect(ayllu.local("B", "Out"), g, ayllu.suppress(p))
    node.connect(ayllu.local("C", "Out"), g, ayllu.inhibit(p))
    node.connect(ayllu.local("D", "Out"), g, ayllu.override_in(p))
    node.connect(ayllu.local("E", "Out"), g, ayllu.override_out(p))
    node.connect(ayllu.local("F", "Out"), g, ayllu.write_inhibit(p))
    # --8<-- [end:connections]
    node.write("B", "Out", 1.0)  # opens a suppress window on G
    node.write("A", "Out", 2.0)  # refused
    assert node.why("G", "Out").counters == {"suppressed": 1}


# --8<-- [start:aggregating]
class Task(ayllu.Behavior):
    # The highest value offered within the last second wins; the port forgets it after that.
    bid = ayllu.Port(0.0, kind="max", window=1.0, name="Bid")


# --8<-- [end:aggregating]


def aggregating_ports() -> None:
    node = ayllu.Node(1, manual=True)
    # --8<-- [start:aggregating-use]
    node.create(Task, "T")
    node.write("T", "Bid", 3.0)
    node.write("T", "Bid", 2.0)  # absorbed: below the maximum
    assert node.read("T", "Bid") == 3.0
    # --8<-- [end:aggregating-use]


# --8<-- [start:ble]
ELIGIBILITY = {1: 0.2, 2: 0.9, 3: 0.5}  # how well suited each robot is


class Worker(ayllu.Behavior):
    out = ayllu.Port(0, name="Out")

    @ayllu.every(hz=10)
    def work(self, ctx: ayllu.Context) -> None:
        ctx.write(self.LOCAL, ELIGIBILITY[ctx.node])
        ctx.write(self.out, ctx.node)


def ble() -> None:
    team = ayllu.Team()  # nodes on one virtual clock
    nodes = [team.add(i) for i in (1, 2, 3)]
    for n in nodes:
        n.create(Worker, "W")
        # Join the group: the most eligible claims the task, write-inhibiting the others' Out.
        n.ble_join("W", "Peers", "Out", 2.0)
    team.advance(3.0, tick=0.01)
    assert [claiming(n) for n in nodes] == [False, True, False]  # robot 2 is the most eligible


def claiming(node: ayllu.Node) -> bool:
    status = node.ble_status("W")  # None for a behavior in no BLE group
    return status is not None and bool(status.claiming)


# --8<-- [end:ble]


def main() -> None:
    behaviors_and_processes()
    connections()
    aggregating_ports()
    ble()
    print("every concept ran as the page says")


if __name__ == "__main__":
    main()
