"""The ROS 2 body's entry point from Python (``Node.install_ros2_body``) says what went wrong,
whole, with the exception class a Python programmer would catch.

Run by ``make test-python`` against the default wheel, built without the ROS 2 body: the call
raises ``ayllu.AylluError`` saying how to build a wheel that has it. Run by
``make ros2-python`` (``AYLLU_TEST_ROS2=1``) against the wheel built with the cargo feature
``ros2``: a wrong mapping file raises ``ayllu.InvalidError`` (a ``ValueError``) naming the file,
the field and the fix; a missing one ``FileNotFoundError``. No DDS participant is started (each
call fails before one would be).
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

import ayllu

# Set by `make ros2-python`, which runs this file against the module it built with the body.
ROS2 = os.environ.get("AYLLU_TEST_ROS2") == "1"

# A mapping file with a misspelt key: the message names the file, where, and the key meant.
BAD_MAPPING = '[[topic]]\nname = "scan"\ntype = "sensor_msgs/msg/LaserScan"\ndirections = "in"\n'

WITHOUT = "this ayllu wheel was built without the ROS 2 body: build it with `make ros2-python` (docs/ros2.md)"


def expect_without(node: ayllu.Node, given: object) -> None:
    """The default wheel's answer to any call: how to build one with the body."""
    with pytest.raises(ayllu.AylluError) as raised:
        node.install_ros2_body(given)  # type: ignore[arg-type]
    assert str(raised.value) == WITHOUT
    # Nothing is wrong with the argument: not a ValueError a caller might take for one.
    assert not isinstance(raised.value, ValueError)
    # Nothing was installed: the node has no body behaviors.
    assert node.report()["behaviors"] == []


# Each test asserts what the wheel under test must do: the default wheel (make test-python)
# says how to get the body; the ROS 2 wheel (make ros2-python) reports the mapping's mistake.
# Neither build skips a test.


def test_a_wrong_mapping_file_raises_invalid_error_with_its_whole_reason(tmp_path: Path) -> None:
    node = ayllu.Node(1, manual=True)
    path = tmp_path / "robot.toml"
    path.write_text(BAD_MAPPING)
    if not ROS2:
        expect_without(node, path)
        expect_without(node, str(path))
        return
    with pytest.raises(ayllu.InvalidError) as raised:
        node.install_ros2_body(str(path))
    assert isinstance(raised.value, ValueError)
    message = str(raised.value)
    assert message.startswith(f"{path}: "), message
    assert "unknown key `directions`: did you mean `direction`?" in message, message


def test_a_missing_mapping_file_raises_file_not_found(tmp_path: Path) -> None:
    node = ayllu.Node(1, manual=True)
    if not ROS2:
        expect_without(node, tmp_path / "missing.toml")
        return
    with pytest.raises(FileNotFoundError, match=r"missing\.toml"):
        node.install_ros2_body(tmp_path / "missing.toml")
