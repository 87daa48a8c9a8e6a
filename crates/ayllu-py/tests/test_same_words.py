"""Seconds are checked once, in the core (`Duration::try_from_secs_f64`, and
`try_from_positive_secs` where zero means nothing), and C, Python and the `ayllu` tool refuse the
same numbers in the same words, each after its own prefix. This test holds the three against
each other: the C library's `ay_clock_advance` (through ctypes, on the library `make test` built
beside the tool), Python's `Node.advance`, and the tool's `--timeout`."""

from __future__ import annotations

import ctypes
import os
import subprocess
from pathlib import Path

import pytest

import ayllu

# Refused by every check: negative, not a number, beyond 584 years, under the clock's 1 ns.
BAD = [-1.0, -1e300, float("nan"), float("inf"), 1e300, 1e-12]


def tool() -> Path:
    path = Path(os.environ.get("AYLLU_BIN", "../../target/debug/ayllu")).resolve()
    assert path.exists(), f"the ayllu tool is not built at {path} (make test builds it first; or set AYLLU_BIN)"
    return path


def c_library() -> ctypes.CDLL:
    path = tool().parent / "libayllu_c.so"
    assert path.exists(), f"libayllu is not built at {path} (make test builds it with the tool)"
    lib = ctypes.CDLL(str(path))
    lib.ay_clock_new.argtypes = [ctypes.POINTER(ctypes.c_void_p)]
    lib.ay_clock_advance.argtypes = [ctypes.c_void_p, ctypes.c_double]
    lib.ay_clock_free.argtypes = [ctypes.c_void_p]
    lib.ay_last_error.restype = ctypes.c_char_p
    return lib


def c_words(lib: ctypes.CDLL, seconds: float) -> str:
    """The core's words in C's refusal of `seconds` as a clock's step: after
    `ay_clock_advance: the step: `."""
    clock = ctypes.c_void_p()
    assert lib.ay_clock_new(ctypes.byref(clock)) == 0
    try:
        assert lib.ay_clock_advance(clock, seconds) != 0, seconds
        message: str = lib.ay_last_error().decode()
    finally:
        lib.ay_clock_free(clock)
    prefix = "ay_clock_advance: the step: "
    assert message.startswith(prefix), message
    return message[len(prefix) :]


def cli_stderr(seconds: float) -> str:
    run = subprocess.run(
        [str(tool()), "list", "1", f"--timeout={seconds!r}"], capture_output=True, text=True, timeout=30, check=False
    )
    assert run.returncode == 2, run
    return run.stderr


@pytest.mark.parametrize("seconds", BAD, ids=repr)
def test_c_python_and_the_tool_refuse_bad_seconds_in_the_cores_words(seconds: float) -> None:
    words = c_words(c_library(), seconds)
    assert "584 years" in words or "1 ns" in words, words
    with pytest.raises(ayllu.InvalidError) as e:
        ayllu.Node(1, manual=True).advance(seconds)
    assert str(e.value) == f"seconds = {words}"
    assert words in cli_stderr(seconds)


def test_zero_where_a_span_must_be_above_zero_is_refused_alike_in_c_and_the_tool() -> None:
    words = c_words(c_library(), 0.0)
    assert words.startswith("0 s is not allowed here"), words
    assert words in cli_stderr(0.0)
