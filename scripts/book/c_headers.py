"""The C API reference of the book: `python scripts/book/c_headers.py INCLUDE_DIR OUTDIR`.

Renders each public header of libayllu (`ayllu_sys.h`, `ayllu.h`, `ayllustd.h`) as a page of
highlighted source with an anchor per line, and an index page listing every function of the C
ABI and every macro of the paper's layer with the comment written above it, linked to its line.
The headers are the reference (every function's comment says who owns what, which thread may
call it, and each error); this only makes them browsable. Doxygen would need the headers'
comments in its own syntax and a large package, for the same result.
"""

from __future__ import annotations

import re
import sys
from html import escape
from pathlib import Path

from pygments import highlight  # type: ignore[import-untyped]
from pygments.formatters import HtmlFormatter  # type: ignore[import-untyped]
from pygments.lexers import CLexer  # type: ignore[import-untyped]

HEADERS = {
    "ayllu.h": "the paper's macros (ayDefBehaviorClass, ayINTERFACE, ayConnect, ayBLE, ...)",
    "ayllustd.h": "the standard behaviors and the simulator's robot body",
    "ayllu_sys.h": "the C ABI: opaque handles, ay_status codes, one function per operation",
}
STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 70em; padding: 0 1em; color: #222; }
table.api { border-collapse: collapse; width: 100%; }
table.api td { border-top: 1px solid #ddd; padding: 0.3em 0.5em; vertical-align: top; }
table.api td:first-child { white-space: nowrap; font-family: monospace; }
.highlight pre { font-size: 13px; line-height: 1.35; }
"""


def declarations(name: str, text: str) -> list[tuple[str, int, str]]:
    """(identifier, line number, the comment above it) for each function and macro."""
    lines = text.splitlines()
    out: list[tuple[str, int, str]] = []
    for i, line in enumerate(lines):
        m = re.match(r"#define (ay[A-Za-z0-9_]*|seconds|ratepersecond)\b", line) or re.match(
            r"[a-z_][a-z0-9_ *]* \**(ay_[a-z0-9_]+)\(", line
        )
        if not m or m.group(1).endswith("_"):
            continue  # helpers whose names end in _ are internal
        comment: list[str] = []
        j = i - 1
        while j >= 0 and (lines[j].startswith("//") or lines[j].strip().startswith(("/*", "*"))):
            text_line = lines[j].strip().lstrip("/*").rstrip("*/").strip()
            comment.insert(0, text_line)
            j -= 1
        summary = " ".join(c for c in comment if c and not c.startswith("#")).split(". ")[0]
        out.append((m.group(1), i + 1, summary))
    return out


def page(title: str, body: str) -> str:
    css = HtmlFormatter().get_style_defs(".highlight")
    return (
        f'<!doctype html>\n<html lang="en"><head><meta charset="utf-8"><title>{escape(title)}</title>'
        f"<style>{STYLE}{css}</style></head><body>\n{body}\n</body></html>\n"
    )


def main(include: Path, out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for name, what in HEADERS.items():
        text = (include / name).read_text()
        source = highlight(text, CLexer(), HtmlFormatter(linenos="table", lineanchors="L", anchorlinenos=True))
        body = f'<p><a href="index.html">C API</a> / {escape(name)}: {escape(what)}</p>\n{source}'
        (out / f"{name}.html").write_text(page(name, body))
        for ident, line, summary in declarations(name, text):
            rows.append(
                f'<tr><td><a href="{name}.html#L-{line}">{escape(ident)}</a></td>'
                f"<td>{escape(name)}</td><td>{escape(summary)}</td></tr>"
            )
    headers = "".join(f'<li><a href="{n}.html">{n}</a>: {escape(w)}</li>' for n, w in HEADERS.items())
    body = (
        "<h1>libayllu: the C API</h1>\n"
        '<p><a href="../../index.html">The book</a> · guide: <a href="../../c-api.html">c-api</a> · '
        'errors: <a href="../../troubleshooting.html#c-status-codes">troubleshooting</a></p>\n'
        f"<ul>{headers}</ul>\n<h2>Every function and macro</h2>\n"
        f'<table class="api">{"".join(rows)}</table>'
    )
    (out / "index.html").write_text(page("libayllu: the C API", body))
    print(f"c_headers: {len(rows)} functions and macros from {len(HEADERS)} headers into {out}")


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]))
