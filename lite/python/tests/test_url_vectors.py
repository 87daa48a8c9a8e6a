"""The ``udp://`` URL's shared vectors (``spec/vectors/urls.json``): :func:`parse_url`
accepts every URL the file says is good, with exactly the values it lists, and refuses every
other one with a message naming the bad part, as the Rust runtime's parser and AylluLite's C
parser do with the same file. ``group``, ``state``, ``operator`` and ``spin_us`` are a full
node's options: a lite parser checks their form and keeps nothing of them, so their values are
not compared here (their refusals are)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

import ayllu_lite as al

VECTORS = Path(__file__).resolve().parents[3] / "spec" / "vectors" / "urls.json"
URLS: list[dict[str, Any]] = json.loads(VECTORS.read_text())["urls"]


def _addr(text: str) -> tuple[str, int]:
    host, _, port = text.rpartition(":")
    return (host, int(port))


def _expected(field: str, want: Any) -> tuple[str, Any] | None:
    """The :func:`parse_url` key and value a vector's field stands for (``None``: not kept)."""
    if field in ("team", "ttl", "mtu", "name"):
        return field, want
    if field == "hello_ms":
        return "hello_interval_ms", want
    if field == "key":
        return "key", bytes.fromhex(want)
    if field == "peers":
        return "bootstrap", [_addr(p) for p in want]
    if field in ("bind", "broadcast", "discovery"):
        return field, _addr(want)
    if field in ("groups", "state", "operator", "spin_us"):
        return None
    raise AssertionError(f"the vectors list `{field}`, which this test does not know")


def test_the_file_holds_the_whole_set() -> None:
    assert len(URLS) > 40
    assert any(v["expect"]["ok"] for v in URLS) and any(not v["expect"]["ok"] for v in URLS)


@pytest.mark.parametrize("vector", URLS, ids=[v["name"] for v in URLS])
def test_url_vector(vector: dict[str, Any]) -> None:
    expect = vector["expect"]
    if not expect["ok"]:
        with pytest.raises(ValueError) as refused:
            al.parse_url(vector["url"])
        assert expect["mentions"] in str(refused.value)
        return
    options = al.parse_url(vector["url"])
    for field, want in expect.items():
        if field == "ok":
            continue
        pair = _expected(field, want)
        if pair is not None:
            assert options[pair[0]] == pair[1], field
    # What the URL gives is what a LiteNode takes.
    with al.LiteNode(1, **{**options, "bind": ("127.0.0.1", 0)}):
        pass
