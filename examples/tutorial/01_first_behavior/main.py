"""Tutorial 1, a first behavior (docs/tutorials/01-first-behavior.md), in Python: the class Avoid
with two ports, a slot, a monostable and two processes, on a node with a manual clock.

Run: `python examples/tutorial/01_first_behavior/main.py` (with the `ayllu` package installed).
Exits non-zero (an AssertionError) if what the tutorial says does not happen.
"""

import ayllu


class Avoid(ayllu.Behavior):
    range = ayllu.Port(10.0, name="Range")  # metres, written by a sonar
    turn = ayllu.Port(0.0, name="Turn")  # rad/s, to the motors
    seen = ayllu.Slot(0, name="Seen")  # internal: not connectable
    backing = ayllu.Monostable(name="Backing")  # high for a while after a trigger

    @ayllu.on_write(range)  # runs whenever Range accepts a value
    def react(self, ctx: ayllu.Context) -> None:
        r = ctx.get(self.range)  # None when the value is stale (rule S4)
        if r is not None and r < 0.5:
            ctx.trigger(self.backing, 2.0)
            ctx.set_slot(self.seen, ctx.slot(self.seen) + 1)

    @ayllu.every(hz=10)
    def steer(self, ctx: ayllu.Context) -> None:
        ctx.write(self.turn, 1.0 if ctx.is_high(self.backing) else 0.0)


def main() -> None:
    node = ayllu.Node(1, manual=True)  # time moves only when we say
    node.create(Avoid, "A")

    node.write("A", "Range", 0.3)  # at 0 s, as a sonar would
    node.step()  # React, then Steer's first activation
    print(f"0.0 s: Range 0.3 m -> Turn {node.read('A', 'Turn')}, Backing {node.monostable('A', 'Backing')}")
    assert node.read("A", "Turn") == 1.0 and node.monostable("A", "Backing")

    for tenth in range(1, 21):  # 2 s in ten steps a second
        node.set_time(tenth / 10)
    print(f"2.0 s: Turn {node.read('A', 'Turn')}, Backing {node.monostable('A', 'Backing')}")
    assert node.read("A", "Turn") == 0.0, "the monostable fell after 2 s, so Steer writes 0"
    assert not node.monostable("A", "Backing")
    print(node.why("A", "Turn"))


if __name__ == "__main__":
    main()
