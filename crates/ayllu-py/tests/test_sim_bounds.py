"""A scenario out of the simulator's bounds is refused by ``sim.run`` with a ``ValueError``
naming the field (the Rust library's check: docs/cmommt.md, "What a scenario may hold"), never
with a panic or an abort; NaN crosses to the simulator and is named too; anything but a
scenario is a ``TypeError``."""

from __future__ import annotations

import math

import pytest

from ayllu import sim


def short() -> sim.Scenario:
    return sim.Scenario.paper("BLE", seed=1).with_(duration=2.0)


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"world.arena": [0.0, 0.0]}, r"^world\.arena: \[0, 0\] is not a usable arena: each side must be finite"),
        ({"world.arena": [1e7, 1e7]}, r"^world\.arena: \[1e7, 1e7\]"),
        ({"world.max_speed": -1.0}, r"^world\.max_speed: -1 is not a usable speed"),
        ({"world.robot_radius": 100.0}, r"^world\.robot_radius: 100 "),
        ({"world.sonar_beams": 100_000_000}, r"^world\.sonar_beams: 100000000 "),
        ({"world.targets": []}, r"^world\.targets: 0 targets "),
        ({"duration": math.nan}, r"^duration: NaN is not a usable duration: must be finite and in \(0, 1e9\] s"),
        ({"duration": math.inf}, r"^duration: inf "),
        ({"duration": 1e300}, r"^duration: 1e300 "),
        ({"radio.loss": 2.0}, r"^radio\.loss: 2 is not a usable probability"),
        ({"radio.range": -math.inf}, r"^radio\.range: -inf "),
        ({"robots": 0}, r"^robots: 0 is not a usable team"),
    ],
)
def test_a_scenario_out_of_bounds_raises_value_error_naming_the_field(fields: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        sim.run(short().with_(**fields))


def test_kills_and_python_controllers_are_checked_before_anything_is_built() -> None:
    with pytest.raises(ValueError, match=r"^kills\[0\]\.robot: 99 is not a usable robot"):
        sim.run(short().kill(1.0, robot=99))
    built = []

    def controller(robot: sim.RobotBuilder) -> None:
        built.append(robot.id)

    with pytest.raises(ValueError, match=r"^world\.arena"):
        sim.run(short().with_(world__arena=[0.0, 0.0]), controller)
    assert built == [], "no robot was built for a refused scenario"


def test_run_takes_a_scenario() -> None:
    with pytest.raises(TypeError, match=r"sim\.Scenario"):
        sim.run(None)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="dict"):
        sim.run(short().data)  # type: ignore[arg-type]


def test_too_many_targets_are_refused_before_the_list_is_made() -> None:
    with pytest.raises(ValueError, match=r"^targets: 1000000000000 "):
        sim.Scenario.sized("BLE", 3, 10**12, 1)
