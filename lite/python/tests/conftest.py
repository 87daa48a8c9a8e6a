"""pytest setup for the AylluLite Python tests: makes the one-file module importable from
any working directory (the tests run as `python3 -m pytest lite/python/tests -q` from the
repository root) without installing anything."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
