"""Tutorial 2, two behaviors in subsumption (docs/tutorials/02-subsumption.md), in Python: Wander
drives the motor; Avoid takes it over through an OverrideIn connection while an obstacle is near,
and gives it back half a second after its last command.

Exits non-zero (an AssertionError) if what the tutorial says does not happen.
"""

import ayllu


class Wander(ayllu.Behavior):
    turn = ayllu.Port(0.0, name="Turn")

    @ayllu.every(hz=10)
    def drift(self, ctx: ayllu.Context) -> None:
        ctx.write(self.turn, 0.2)


class Avoid(ayllu.Behavior):
    range = ayllu.Port(10.0, name="Range")
    turn = ayllu.Port(0.0, name="Turn")

    @ayllu.on_write(range)
    def react(self, ctx: ayllu.Context) -> None:
        r = ctx.get(self.range)
        if r is not None and r < 0.5:
            ctx.write(self.turn, 1.0)  # hard turn away from the obstacle


class Motor(ayllu.Behavior):
    turn = ayllu.Port(0.0, name="Turn")


def main() -> None:
    node = ayllu.Node(1, manual=True)
    node.create(Wander, "WANDER")
    node.create(Avoid, "AVOID")
    node.create(Motor, "MOTOR")
    # The lower layer drives the motor...
    node.connect(ayllu.local("WANDER", "Turn"), ayllu.local("MOTOR", "Turn"))
    # ...and the higher layer subsumes it: for 0.5 s after each of Avoid's values, only Avoid
    # may write MOTOR.Turn.
    node.connect(ayllu.local("AVOID", "Turn"), ayllu.local("MOTOR", "Turn"), ayllu.override_in(0.5))

    turn, during = {}, ""
    for tenth in range(41):
        node.set_time(tenth / 10)
        if 10 <= tenth < 20:
            node.write("AVOID", "Range", 0.3)  # an obstacle from 1 s to 2 s
            node.step()
        turn[tenth] = node.read("MOTOR", "Turn")
        if tenth == 15:
            during = str(node.why("MOTOR", "Turn"))  # while Avoid holds the motor
        if tenth % 5 == 0:
            print(f"{tenth / 10:.1f} s  MOTOR.Turn = {turn[tenth]}")
    assert turn[5] == 0.2, "Wander drives the motor before the obstacle"
    assert turn[15] == 1.0, "Avoid has taken the motor over"
    assert turn[22] == 1.0, "Avoid's last command still holds: its window lasts 0.5 s"
    assert turn[30] == 0.2, "Wander has the motor back"
    refused = node.why("MOTOR", "Turn").counters["overridden_in"]
    print(f"Wander's values refused while Avoid held the motor: {refused} (overridden_in)")
    assert refused >= 10
    print(f"why, at 1.5 s:\n{during}")
    assert "input     BLOCKED (overridden_in)" in during


if __name__ == "__main__":
    main()
