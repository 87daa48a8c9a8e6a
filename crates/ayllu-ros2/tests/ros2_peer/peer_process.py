#!/usr/bin/env python3
"""What every peer script does as a process: JSON lines out, a stop on SIGTERM.

What it promises: `emit` writes one JSON object a line and flushes it, and a
reader that went away ends the output quietly instead of the script; a `Stop`
installed as a signal handler only sets `requested`, which the scripts' bounded
loops check, so they end by themselves and print their last line.
"""

from __future__ import annotations

import json
import os
import sys
from typing import Any


class Stop:
    """A signal handler that asks the script's loop to end."""

    def __init__(self) -> None:
        self.requested = False

    def __call__(self, signum: int, frame: Any) -> None:
        self.requested = True


def emit(obj: dict[str, Any]) -> None:
    """One JSON line on stdout; a reader that went away is not an error."""
    try:
        sys.stdout.write(json.dumps(obj, allow_nan=False) + "\n")
        sys.stdout.flush()
    except BrokenPipeError:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
