"""Flight recording from Python (spec/flight-recorder.md): a node whose process is Python
code (here reading a random source the replay cannot know) records into an MCAP file; an
independent reader (the ``mcap`` package from PyPI, with ``mcap-ros2-support`` to decode CDR)
finds the four CDR channels with their ros2msg schema, and the recording replays with no Python
code, reproducing every accepted value bit for bit."""

from __future__ import annotations

import contextlib
import json
import random
from pathlib import Path

# The independent reader (scripts/python-venv installs it): without it this fails, not skips.
import mcap.reader as mcap_reader
import pytest
from mcap_ros2.decoder import DecoderFactory

import ayllu

RNG = random.Random(42)


class Noisy(ayllu.Behavior):
    inp = ayllu.Port(0.0, name="In")
    out = ayllu.Port(0.0, name="Out")

    @ayllu.on_write(inp)
    def jitter(self, ctx: ayllu.Context) -> None:
        # A "sensor" only the live process can read: the replay has only its effects.
        ctx.write(self.out, ctx.read(self.inp) + RNG.random())


def record_run(path: Path, steps: int = 100) -> list[float]:
    node = ayllu.Node(1, manual=True)
    node.record(path)
    node.create(Noisy, "N")
    outs = []
    for k in range(steps):
        node.write("N", "In", k / 7.0)
        node.advance(0.01, tick=0.01)
        outs.append(node.read("N", "Out"))
    stats = node.stop_recording()
    assert stats is not None and stats["written"] > 3 * steps and stats["error"] is None
    assert node.stop_recording() is None
    return outs


def test_an_independent_reader_decodes_the_cdr_channels_with_their_schema(tmp_path: Path) -> None:
    path = tmp_path / "py.mcap"
    outs = record_run(path)
    with path.open("rb") as f:
        reader = mcap_reader.make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert summary is not None
        topics = {c.topic: c for c in summary.channels.values()}
        assert sorted(topics) == ["/ayllu/accepted", "/ayllu/input", "/ayllu/process", "/ayllu/structure"]
        for channel in topics.values():
            assert channel.message_encoding == "cdr"
            schema = summary.schemas[channel.schema_id]
            assert schema.encoding == "ros2msg" and schema.name == "ayllu_msgs/msg/FlightEntry"
        accepted = [m for _, _, _, m in reader.iter_decoded_messages(topics=["/ayllu/accepted"])]
    out_values = [a.float_value for a in accepted if a.behavior == "N" and a.name == "Out"]
    # Floats come back exactly: what the process wrote is what the file says.
    assert out_values == outs
    assert all(a.type == 3 for a in accepted)  # float


def test_the_recording_replays_without_the_python_code(tmp_path: Path) -> None:
    path = tmp_path / "replay.mcap"
    record_run(path, steps=50)
    assert ayllu.check_recording(path) == 100, "every In and Out value compared"


def test_a_rolling_recording_keeps_its_last_seconds_and_replays_from_a_checkpoint(tmp_path: Path) -> None:
    path = tmp_path / "rolling.mcap"
    node = ayllu.Node(3, manual=True)
    node.record(path, keep_last=2.0)
    node.create(Noisy, "N")
    for k in range(1000):
        node.write("N", "In", k / 7.0)
        node.advance(0.01, tick=0.01)
    stats = node.stop_recording()
    assert stats is not None and stats["deleted"] > 5 and stats["error"] is None, stats
    assert not path.exists(), "the first segment is gone: only the last window is kept"
    kept = sorted(tmp_path.glob("rolling.*.mcap"))
    assert 1 <= len(kept) <= 4, kept
    # The oldest segment kept opens with a checkpoint, on its own channel.
    with kept[0].open("rb") as f:
        reader = mcap_reader.make_reader(f, decoder_factories=[DecoderFactory()])
        _, channel, _, first = next(iter(reader.iter_decoded_messages()))
        assert channel.topic == "/ayllu/checkpoint" and first.event == "checkpoint"
        assert json.loads(first.json)["snapshot"]["id"] == 3
    # Each In and Out of the last 2 s to 3 s (checkpoints come every second at least), compared
    # bit for bit with no Python code.
    assert 400 <= ayllu.check_recording(path) <= 600


def test_misuse_is_refused_with_a_reason(tmp_path: Path) -> None:
    node = ayllu.Node(2, manual=True)
    with pytest.raises(ayllu.InvalidError, match="65536"):
        node.record(tmp_path / "small.mcap", max_bytes=1000)
    node.create(Noisy, "N")
    with pytest.raises(ayllu.AylluError, match="before defining"):
        node.record(tmp_path / "late.mcap")
    (tmp_path / "bad.mcap").write_bytes(b"not a recording")
    with pytest.raises(ayllu.InvalidError, match="not an MCAP file"):
        ayllu.check_recording(tmp_path / "bad.mcap")


def test_files_that_made_the_mcap_reader_panic_raise_invalid_error() -> None:
    # The MCAP magic then 0xff bytes (a record length of 2**64 - 1) used to panic inside the
    # mcap crate: a PanicException, not an ayllu error. Every malformed file of the Rust
    # tests (crates/ayllu/tests/malformed_recordings/) is an InvalidError or a recording.
    inputs = Path(__file__).parents[2] / "ayllu" / "tests" / "malformed_recordings"
    with pytest.raises(ayllu.InvalidError, match=r"not an Ayllu flight recording .*at byte 8"):
        ayllu.check_recording(inputs / "garbage.mcap")
    files = sorted(inputs.glob("*.mcap"))
    assert len(files) == 8
    for f in files:
        with contextlib.suppress(ayllu.AylluError):
            ayllu.check_recording(f)


def test_a_teams_recordings_check_as_one_system(tmp_path: Path) -> None:
    # Two nodes of a deterministic team, each recording; node 1's values cross to node 2 and
    # back. The team check matches every remote value with its sending and bounds the clocks.
    team = ayllu.Team()
    nodes = [team.add(i) for i in (1, 2)]
    paths = [tmp_path / f"n{i}.mcap" for i in (1, 2)]
    for node, path in zip(nodes, paths):
        node.record(path)
        node.create(Noisy, "N")
    nodes[0].connect(ayllu.local("N", "Out"), ayllu.remote(2, "N", "In"))
    nodes[1].connect(ayllu.local("N", "Out"), ayllu.remote(1, "N", "In"))
    for k in range(50):
        nodes[0].write("N", "In", k / 3.0)
        team.advance(0.02, tick=0.01)
    for node in nodes:
        node.stop_recording()
    timeline = tmp_path / "team.mcap"
    result = ayllu.check_team(paths, mcap=timeline)
    assert result["passed"], result
    assert result["unexplained"] == 0 and result["accepted_remote"] >= 40, result
    assert [m["from"] for m in result["matched"]] == [1, 2], result
    # One clock (the team's): node 2's offset from node 1 is within its bound of zero.
    clock = result["clocks"][1]
    assert clock["low_s"] <= 0.0 <= clock["high_s"], clock
    # The merged timeline opens in the independent reader: both nodes' ports, in time order.
    with timeline.open("rb") as f:
        reader = mcap_reader.make_reader(f)
        topics = {c.topic for c in reader.get_summary().channels.values()}  # type: ignore[union-attr]
        times = [m.log_time for _, _, m in reader.iter_messages()]
    assert {"/n1/N/In", "/n2/N/In"} <= topics, topics
    assert times == sorted(times) and len(times) == sum(r["values"] for r in result["replayed"])
    # Why node 2's N.In held its value: the message from node 1, and what wrote its source.
    chain = ayllu.why_team(paths, 2, 0.5, "N", "In", depth=1)
    kinds = [(link["node"], link["kind"]) for link in chain]
    assert (1, "message") in kinds and (1, "activation") in kinds, chain
    with pytest.raises(ayllu.InvalidError):
        ayllu.check_team([tmp_path / "missing.mcap"])
