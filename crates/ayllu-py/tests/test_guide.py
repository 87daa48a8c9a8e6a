"""docs/python.md runs: every ```python block, in order, in one namespace (from the repository
root, as a reader would), and the package's own doctests."""

from __future__ import annotations

import doctest
import os
import re
from pathlib import Path

import pytest

import ayllu
import ayllu.sim

ROOT = Path(__file__).resolve().parents[3]


def blocks() -> list[str]:
    text = (ROOT / "docs" / "python.md").read_text()
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


def test_the_guide_runs_and_draws_its_plot(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)
    plot = tmp_path / "coverage.png"
    namespace: dict[str, object] = {"PLOT_PATH": str(plot), "__name__": "guide"}
    code = blocks()
    assert len(code) >= 8
    for i, block in enumerate(code):
        try:
            exec(compile(block, f"docs/python.md block {i + 1}", "exec"), namespace)
        except Exception as e:
            raise AssertionError(f"docs/python.md, python block {i + 1} failed: {e!r}\n{block}") from e
    assert plot.stat().st_size > 10_000, "the plot was drawn"
    assert os.getcwd() == str(ROOT)


@pytest.mark.parametrize("module", [ayllu, ayllu.sim])
def test_the_docstring_examples_run(module: object) -> None:
    result = doctest.testmod(module)  # type: ignore[arg-type]
    assert result.attempted > 0 and result.failed == 0
