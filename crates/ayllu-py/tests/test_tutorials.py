"""The book's tutorials (docs/tutorials/) in Python, and the rule that keeps the book honest.

Each tutorial's `main.py` runs as a reader runs it (a fresh interpreter, the installed `ayllu`),
and exits non-zero when what its page says does not happen; its shell blocks (`*.sh`) run against
the `ayllu` binary of this build. Every fenced code block of the tutorials and the concepts page
must be an included source file (pymdownx.snippets `--8<--`) of a program these tests (or the
Rust and C tutorial tests) run, or a `text` block of output: no code is shown that nothing runs.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
TUTORIALS = ROOT / "examples" / "tutorial"
PAGES = [*sorted((ROOT / "docs" / "tutorials").glob("*.md")), ROOT / "docs" / "concepts.md"]


def run(args: list[str], cwd: Path, env: dict[str, str] | None = None) -> str:
    done = subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, f"{args} exited {done.returncode}\n{done.stdout}\n{done.stderr}"
    return done.stdout


def test_the_concepts_page_code_runs(tmp_path: Path) -> None:
    out = run([sys.executable, str(TUTORIALS / "00_concepts" / "main.py")], tmp_path)
    assert out == "every concept ran as the page says\n"


def test_the_pictures_are_what_the_runtime_does(tmp_path: Path) -> None:
    # docs/img is committed (the pages render without a build); it must be what the
    # generator draws from the runtime today.
    run([sys.executable, str(ROOT / "scripts" / "book" / "pictures.py"), str(tmp_path)], ROOT)
    drawn = sorted(p.name for p in tmp_path.glob("*.svg"))
    assert len(drawn) == 6
    for name in drawn:
        assert (tmp_path / name).read_text() == (ROOT / "docs" / "img" / name).read_text(), (
            f"docs/img/{name} is not what scripts/book/pictures.py draws now: run `make docs` and commit docs/img"
        )


def test_1_a_first_behavior(tmp_path: Path) -> None:
    out = run([sys.executable, str(TUTORIALS / "01_first_behavior" / "main.py")], tmp_path)
    assert "0.0 s: Range 0.3 m -> Turn 1.0, Backing True" in out
    assert "2.0 s: Turn 0.0, Backing False" in out


def test_2_two_behaviors_in_subsumption(tmp_path: Path) -> None:
    out = run([sys.executable, str(TUTORIALS / "02_subsumption" / "main.py")], tmp_path)
    assert "1.5 s  MOTOR.Turn = 1.0" in out and "3.0 s  MOTOR.Turn = 0.2" in out


def test_3_two_nodes_over_udp(tmp_path: Path) -> None:
    out = run([sys.executable, str(TUTORIALS / "03_two_nodes_udp" / "main.py")], tmp_path)
    assert "supplied by node 1's connection" in out


def test_4_a_ble_group_in_the_simulator(tmp_path: Path) -> None:
    out = run([sys.executable, str(TUTORIALS / "04_ble_in_the_simulator" / "main.py")], tmp_path)
    assert "alive at the end: {1: False, 2: True, 3: True}" in out


def test_5_a_study_with_a_sweep_and_a_plot(tmp_path: Path) -> None:
    plot = tmp_path / "coverage_vs_loss.png"
    out = run([sys.executable, str(TUTORIALS / "05_study_sweep_plot" / "main.py"), str(plot)], tmp_path)
    assert out.count(" loss ") == 8 and plot.stat().st_size > 10_000


def quoted(page: str) -> str:
    """The first unindented ```text block of a tutorial page: the output the page quotes."""
    text = (ROOT / "docs" / "tutorials" / page).read_text()
    start = text.index("\n```text\n") + len("\n```text\n")
    return text[start : text.index("```", start)]


def ayllu_bin() -> Path:
    found = os.environ.get("AYLLU_BIN")
    path = Path(found) if found else ROOT / "target" / "debug" / "ayllu"
    if not path.exists():
        subprocess.run(["cargo", "build", "-q", "-p", "ayllu-cli"], cwd=ROOT, check=True, timeout=900)
    return path


def test_5_the_sweep_from_the_shell(tmp_path: Path) -> None:
    env = dict(os.environ, PATH=f"{ayllu_bin().parent}:{os.environ['PATH']}", OUT=str(tmp_path))
    out = run(["bash", "-euo", "pipefail", str(TUTORIALS / "05_study_sweep_plot" / "sweep.sh")], ROOT, env)
    assert "cell4: radio.loss = 0.9" in out and "24 runs" in out
    assert (tmp_path / "loss-study" / "runs.csv").read_text().count("\n") == 25


def test_6_recording_a_team_and_asking_why_in_the_past(tmp_path: Path) -> None:
    path = f"{ayllu_bin().parent}:{Path(sys.executable).parent}:{os.environ['PATH']}"
    env = dict(os.environ, PATH=path, OUT=str(tmp_path))
    script = TUTORIALS / "06_recording_why_in_the_past" / "replay.sh"
    out = run(["bash", "-euo", "pipefail", str(script)], ROOT, env)
    assert "n2.mcap: 198 accepted values replay bit for bit" in out
    at_2s, at_7s = out.split("n2:W.Out (normal float) at ")[1:3]
    assert at_2s.startswith("2.000s") and "own writes BLOCKED (write_inhibited)" in at_2s
    assert "write-inhibit held by n1/" in at_2s, "robot 1's claim is named"
    assert at_7s.startswith("7.000s") and "own writes open" in at_7s
    assert "accepted values reproduced bit for bit" in out
    assert out.endswith(quoted("06-recording-why-in-the-past.md")), "the page quotes what the replay prints"


def test_7_joining_from_a_microcontroller(tmp_path: Path) -> None:
    # The C client built for the host stands in for the microcontroller's firmware.
    subprocess.run(["make", "-s", "-C", str(ROOT / "lite" / "c"), "build/udp_client"], check=True, timeout=300)
    client = ROOT / "lite" / "c" / "build" / "udp_client"
    out = run([sys.executable, str(TUTORIALS / "07_ayllu_lite" / "main.py"), str(client)], tmp_path)
    assert "robot's MOTOR.Speed = 0.4, supplied by node 50" in out
    assert "after udp_client: MOTOR.Speed = 0.25" in out
    assert out == quoted("07-ayllu-lite.md"), "the page quotes what the program prints"


# Tutorial 8 (two machines) needs two network namespaces: its Python robot runs against the
# Rust one, and the page's recipe, in crates/ayllu-cli/tests/tool/two_machines.rs.


def fenced_blocks(text: str) -> list[tuple[str, str]]:
    """(language, body) of every fenced block, including those indented inside tabs."""
    return [(m.group(2), m.group(3)) for m in re.finditer(r"^( *)```(\w*)[^\n]*\n(.*?)^\1```", text, re.S | re.M)]


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_every_code_block_of_the_book_is_a_file_a_test_runs(page: Path) -> None:
    blocks = fenced_blocks(page.read_text())
    assert blocks, f"{page} shows no code"
    for lang, body in blocks:
        if lang == "text":
            continue  # output, quoted
        lines = [line.strip() for line in body.splitlines() if line.strip()]
        assert lines and all(line.startswith("--8<--") for line in lines), (
            f"{page.name}: a ```{lang} block that is not an included source file:\n{body}"
        )
        for line in lines:
            name = line.split('"')[1].split(":")[0]
            assert (ROOT / name).is_file(), f"{page.name} includes {name}, which does not exist"
