"""The book in a real browser: the pages are built with MkDocs (strict) into a scratch folder and
Debian's headless Chromium opens them, as `crates/ayllu-sim/tests/simulator/report_chromium.rs` does for
the report page (same browser, same flags, same `AYLLU_SKIP_BROWSER=1` loud skip; install with
`scripts/install-chromium`).

The front page must render styled: from a screenshot, Material's indigo header bar spans the
window and the page is not blank; from the DOM after scripts ran, the navigation lists the
concepts, the tutorials, troubleshooting and the references. The concepts page must show its
pictures (the timelines' colours are on the screenshot) and its Rust | C | Python tabs. The
checker is also run on the front page with its stylesheets taken away, to show it can tell.
`AYLLU_KEEP_BOOK=1` keeps the folder and screenshots for a person to look at.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from matplotlib import image

ROOT = Path(__file__).resolve().parents[3]
CHROMIUM = Path("/usr/bin/chromium")
INDIGO = (0x3F, 0x51, 0xB5)  # Material's default primary colour, the header bar


def browser() -> Path:
    if os.environ.get("AYLLU_SKIP_BROWSER") == "1":
        print("\n*** SKIPPED: the book was NOT checked in a browser (AYLLU_SKIP_BROWSER=1) ***\n", file=sys.stderr)
        pytest.skip("AYLLU_SKIP_BROWSER=1")
    assert CHROMIUM.exists(), f"{CHROMIUM} is missing: run scripts/install-chromium (or AYLLU_SKIP_BROWSER=1)"
    return CHROMIUM


def chromium(page: Path, extra: list[str], size: tuple[int, int] = (1280, 900)) -> str:
    """Headless Chromium on `page`; its stdout. Killed after 60 s (a bounded wait)."""
    with tempfile.TemporaryDirectory() as profile:
        args = [
            str(browser()),
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--no-default-browser-check",
            "--disable-extensions",
            "--hide-scrollbars",
            "--force-device-scale-factor=1",
            "--virtual-time-budget=3000",
            f"--window-size={size[0]},{size[1]}",
            f"--user-data-dir={profile}",
            *extra,
            page.as_uri(),
        ]
        done = subprocess.run(args, capture_output=True, text=True, timeout=60, start_new_session=True)
    assert done.returncode == 0, f"chromium failed on {page}: {done.stderr[-2000:]}"
    return done.stdout


def screenshot(page: Path, size: tuple[int, int] = (1280, 900)) -> np.ndarray:
    """The page as RGB bytes (height, width, 3)."""
    shot = page.with_name(page.stem + "-screenshot.png")
    chromium(page, [f"--screenshot={shot}"], size)
    pixels = image.imread(str(shot))[:, :, :3]
    return np.asarray(np.round(pixels * 255), dtype=np.int32)


def share_of(pixels: np.ndarray, rgb: tuple[int, int, int], tolerance: int = 6) -> float:
    close = np.all(np.abs(pixels - np.array(rgb)) <= tolerance, axis=-1)
    return float(close.mean())


def front_page_problems(site: Path) -> list[str]:
    """Everything wrong with the built front page, in a browser."""
    problems = []
    pixels = screenshot(site / "index.html")
    header = share_of(pixels[:40], INDIGO)
    if header < 0.8:
        problems.append(f"no styled header bar: {header:.0%} of the top 40 rows are Material's indigo")
    colours = len(np.unique(pixels.reshape(-1, 3), axis=0))
    if colours < 50:
        problems.append(f"the page looks blank: {colours} colours")
    dom = chromium(site / "index.html", ["--dump-dom"])
    for words in ["Concepts", "Tutorials", "Troubleshooting", "API references", "A first behavior"]:
        if words not in dom:
            problems.append(f"the navigation does not show {words!r}")
    if "**[" in dom or "](" in dom:
        problems.append("markdown shows through unrendered (`**[` or `](` in the page)")
    return problems


@pytest.fixture(scope="module")
def site() -> Iterator[Path]:
    browser()
    scratch = Path(tempfile.mkdtemp(prefix="ayllu-book-"))
    out = scratch / "book"
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--quiet", "--site-dir", str(out)],
        cwd=ROOT,
        env=env,
        check=True,
        timeout=300,
    )
    yield out
    if os.environ.get("AYLLU_KEEP_BOOK") == "1":
        print(f"\nthe book and its screenshots: {out}", file=sys.stderr)
    else:
        shutil.rmtree(scratch)


def test_the_front_page_renders_styled_with_its_navigation(site: Path) -> None:
    assert front_page_problems(site) == []


def test_the_checker_sees_unrendered_markdown(site: Path) -> None:
    raw = site.parent / "raw"
    shutil.copytree(site, raw)
    page = raw / "index.html"
    page.write_text(page.read_text().replace("</article>", "<p>- **[Concepts](concepts.md)**</p></article>", 1))
    assert any("unrendered" in p for p in front_page_problems(raw))


def test_the_checker_sees_a_page_without_its_styles(site: Path) -> None:
    bare = site.parent / "bare"
    shutil.copytree(site, bare)
    shutil.rmtree(bare / "assets" / "stylesheets")
    problems = front_page_problems(bare)
    assert any("no styled header bar" in p for p in problems), problems


def test_the_concepts_page_shows_its_pictures_and_tabs(site: Path) -> None:
    page = site / "concepts.html"
    pixels = screenshot(page, (1280, 9000))  # tall enough for the whole page
    # The timelines' marks: "stored, passed on" green and the window's blue, drawn by the SVGs.
    assert share_of(pixels, (0x2E, 0x7D, 0x32), 2) > 0.0005, "the timelines' green marks are not on the page"
    assert share_of(pixels, (0x90, 0xCA, 0xF9), 2) > 0.0005, "the timelines' windows are not on the page"
    dom = chromium(page, ["--dump-dom"])
    assert dom.count('class="tabbed-set') == 5, "the Rust | C | Python tabs are missing"
    for label in (">Rust<", ">C<", ">Python<"):
        assert label in dom, f"no tab labelled {label}"
