"""The same configuration as every Ayllu program: a ``udp://`` URL from ``AYLLU_URL`` or the
shared default (team 0, no key, discovery on this machine), parsed with the Rust runtime's
option names, and the same default team when none is given."""

from __future__ import annotations

from pathlib import Path

import pytest

import ayllu_lite as al


def test_the_default_url_is_the_runtimes() -> None:
    assert al.DEFAULT_URL == "udp://0.0.0.0:0?discovery=239.255.65.89:7390&ttl=0"
    o = al.parse_url(al.DEFAULT_URL)
    assert o["bind"] == ("0.0.0.0", 0)
    assert o["discovery"] == ("239.255.65.89", 7390)
    assert o["ttl"] == 0
    assert "team" not in o, "team 0 unless the URL says otherwise"


def test_ayllu_url_wins_over_the_default(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("AYLLU_URL", "udp://127.0.0.1:0?team=3")
    assert al.default_url() == "udp://127.0.0.1:0?team=3"
    monkeypatch.setenv("AYLLU_URL", "  ")
    assert al.default_url() == al.DEFAULT_URL
    monkeypatch.delenv("AYLLU_URL")
    assert al.default_url() == al.DEFAULT_URL


def test_every_option_parses() -> None:
    key = "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff"
    o = al.parse_url(
        f"udp://127.0.0.1:7400?team=7&key={key}&peer=127.0.0.1:7401&peer=127.0.0.1:7402"
        "&broadcast=127.255.255.255:7400&discovery=239.1.2.3:7500&ttl=1&hello_ms=250&name=r1"
    )
    assert o == {
        "bind": ("127.0.0.1", 7400),
        "team": 7,
        "key": bytes.fromhex(key),
        "bootstrap": [("127.0.0.1", 7401), ("127.0.0.1", 7402)],
        "broadcast": ("127.255.255.255", 7400),
        "discovery": ("239.1.2.3", 7500),
        "ttl": 1,
        "hello_interval_ms": 250,
        "name": "r1",
    }


def test_operator_options(tmp_path: Path) -> None:
    # operator_secret=FILE (as `ayllu keygen` writes it) signs; operator= is only checked.
    secret = tmp_path / "operator.secret"
    secret.write_text("11" * 32 + "\n", encoding="ascii")
    public = al.operator_public_key(b"\x11" * 32).hex()
    o = al.parse_url(f"udp://127.0.0.1:0?operator_secret={secret}&operator={public}")
    assert o["operator_secret"] == b"\x11" * 32
    node = al.LiteNode.from_url(5, f"udp://127.0.0.1:0?operator_secret={secret}")
    try:
        assert node.operator_secret == b"\x11" * 32
    finally:
        node.close()
    secret.write_text("not hex", encoding="ascii")
    with pytest.raises(ValueError, match="64 hex digits"):
        al.parse_url(f"udp://127.0.0.1:0?operator_secret={secret}")
    with pytest.raises(ValueError, match="cannot read"):
        al.parse_url(f"udp://127.0.0.1:0?operator_secret={tmp_path / 'absent'}")
    with pytest.raises(ValueError, match="operator"):
        al.parse_url("udp://127.0.0.1:0?operator=abc")


def test_mtu_bounds_what_a_lite_node_sends() -> None:
    # The URL's mtu, as a full node reads it: a value that does not fit is refused at send.
    assert al.parse_url("udp://127.0.0.1:1?mtu=8192")["mtu"] == 8192
    with al.LiteNode.from_url(4, "udp://127.0.0.1:0?mtu=200") as small, al.LiteNode(5, bind=("127.0.0.1", 0)) as big:
        assert (small.mtu, big.mtu) == (200, al.MTU)
        text = "x" * 400
        to_small = big.connection(small.address, "B", "P")
        to_big = small.connection(big.address, "B", "P")
        to_small.send(text)  # fits the default MTU
        with pytest.raises(al.EncodeError):
            to_big.send(text)


def test_a_full_nodes_spin_us_is_accepted() -> None:
    # One AYLLU_URL serves full nodes and lite clients alike.
    al.parse_url("udp://127.0.0.1:1?spin_us=0")
    al.parse_url("udp://127.0.0.1:1?spin_us=1000")


@pytest.mark.parametrize(
    ("url", "needle"),
    [
        ("tcp://127.0.0.1:1", "udp://"),
        ("udp://127.0.0.1:1?team=x", "team"),
        ("udp://127.0.0.1:1?key=+0112233445566778899aabbccddeeff00112233445566778899aabbccddeeff", "hex"),
        ("udp://127.0.0.1:1?discovery=127.0.0.1:7400", "multicast"),
        ("udp://127.0.0.1:1?ttl=256", "ttl"),
        ("udp://127.0.0.1:1?spin_us=1001", "spin_us"),
        ("udp://127.0.0.1:1?mtu=63", "mtu"),
        ("udp://127.0.0.1:1?mtu=8193", "mtu"),
        ("udp://127.0.0.1:1?colour=blue", "unknown option"),
        ("udp://nowhere", "HOST:PORT"),
    ],
)
def test_mistakes_are_named(url: str, needle: str) -> None:
    with pytest.raises(ValueError, match=needle):
        al.parse_url(url)


def test_a_node_from_a_url_greets_its_bootstrap_peer_and_is_greeted_back() -> None:
    # Team defaults to 0 everywhere; `peer=` addresses are greeted without knowing their id.
    with al.LiteNode(5, bind=("127.0.0.1", 0)) as b:
        host, port = b.address
        with al.LiteNode.from_url(4, f"udp://127.0.0.1:0?peer={host}:{port}&hello_ms=50") as a:
            assert (a.team, b.team) == (0, 0)
            for _ in range(100):
                a.poll(0.01)
                b.poll(0.01)
                if 5 in a.peers() and 4 in b.peers():
                    break
            assert 5 in a.peers(), a.counters
            assert 4 in b.peers(), b.counters
