"""Tutorial 3, two nodes over UDP (docs/tutorials/03-two-nodes-udp.md), in Python: robot 1's
sonar writes robot 2's motor across real sockets on loopback. Each node binds port 0 (the system
picks a free one); robot 2 is told where robot 1 is. Both run on background threads (`start()`).

Exits non-zero if no value crosses the network within 10 s.
"""

import time

import ayllu


class Sonar(ayllu.Behavior):
    range = ayllu.Port(0.0, name="Range")

    @ayllu.every(hz=20)
    def ping(self, ctx: ayllu.Context) -> None:
        ctx.write(self.range, 0.75)  # metres


class Motor(ayllu.Behavior):
    speed = ayllu.Port(0.0, name="Speed", lifespan=0.3)  # stale 300 ms after the last command


def main() -> None:
    r1 = ayllu.Node(1, "udp://127.0.0.1:0")
    r2 = ayllu.Node(2, f"udp://127.0.0.1:0?peer={r1.address()}")
    print(f"robot 1 at {r1.address()}, robot 2 at {r2.address()}")
    r1.create(Sonar, "SONAR")
    r2.create(Motor, "MOTOR")
    # A connection whose destination is a port on another node.
    r1.connect(ayllu.local("SONAR", "Range"), ayllu.remote(2, "MOTOR", "Speed"))
    r1.start()
    r2.start()
    deadline = time.monotonic() + 10  # bounded
    while not r2.fresh("MOTOR", "Speed") and time.monotonic() < deadline:
        time.sleep(0.01)
    why = r2.why("MOTOR", "Speed")
    r1.close()
    r2.close()
    supplier = why.supplier
    print(f"MOTOR.Speed on robot 2 = {why.value}, supplied by node {supplier.node}'s connection {supplier.conn}")
    assert why.value == 0.75 and why.supplier.node == 1, "the value crossed the network from robot 1"
    print(why)


if __name__ == "__main__":
    main()
