"""The ``ayllu`` tool against an AylluLite node (a Python ``LiteNode`` on loopback): ``list``
shows the lite node's behaviors and ports (its small LIST), and ``write`` delivers the value
and exits 0, confirming by READ since a lite node has no WHY.

Needs the built tool: ``AYLLU_BIN``, else ``target/debug/ayllu`` (``CARGO_TARGET_DIR``
honoured). ``make test`` builds it first; set ``AYLLU_SKIP_CLI=1`` to skip loudly instead.
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest

import ayllu_lite as al

ROOT = Path(__file__).resolve().parents[3]


def ayllu_bin() -> str:
    if os.environ.get("AYLLU_SKIP_CLI") == "1":
        pytest.skip("AYLLU_SKIP_CLI=1: the ayllu tool against a lite node was NOT checked")
    explicit = os.environ.get("AYLLU_BIN")
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    path = Path(explicit) if explicit else target / "debug" / "ayllu"
    if not path.is_file():
        pytest.fail(f"{path} is missing: run `cargo build -p ayllu-cli` (or set AYLLU_SKIP_CLI=1)")
    return str(path)


def run(args: list[str], url: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "AYLLU_URL": url}
    return subprocess.run(args, capture_output=True, text=True, timeout=30, env=env, check=False)


def test_the_tool_lists_and_writes_a_lite_node() -> None:
    tool = ayllu_bin()
    with al.LiteNode(77, bind=("127.0.0.1", 0), name="lite-77") as lite:
        lite.expose("Drive", "Speed", 0.0)
        lite.expose("Drive", "Mode", "")
        lite.start()
        host, port = lite.address
        url = f"udp://127.0.0.1:0?peer={host}:{port}"

        listed = run([tool, "list", "77"], url)
        assert listed.returncode == 0, listed
        assert "AylluLite" in listed.stdout and "Drive: Speed, Mode" in listed.stdout, listed.stdout

        report = run([tool, "list", "77", "--json"], url)
        assert report.returncode == 0, report
        assert json.loads(report.stdout)["lite"] is True

        wrote = run([tool, "write", "77", "Drive.Speed", "2.5"], url)
        assert wrote.returncode == 0, wrote
        assert "(lite)" in wrote.stdout, wrote.stdout
        assert lite.get("Drive", "Speed") == 2.5

        as_json = run([tool, "write", "77", "Drive.Mode", "auto", "--json"], url)
        assert as_json.returncode == 0, as_json
        assert json.loads(as_json.stdout)["lite"] is True
        assert lite.get("Drive", "Mode") == "auto"
