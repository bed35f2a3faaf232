"""Shared by the gallery scripts: the size switch and where figures go.

``DTTMM_EXAMPLES_QUICK=1`` (or ``--quick`` on the command line) runs every script at a small
size (the smoke test, ``tests/test_examples.py``); ``DTTMM_EXAMPLES_OUT`` is the folder for the
figures (default ``out/examples``).
"""

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CASES = ROOT / "experiments" / "cases"
QUICK = os.environ.get("DTTMM_EXAMPLES_QUICK") == "1" or "--quick" in sys.argv
OUT = Path(os.environ.get("DTTMM_EXAMPLES_OUT", "out/examples"))


def figure_path(name: str) -> Path:
    """``OUT/name``, the folder created."""
    OUT.mkdir(parents=True, exist_ok=True)
    return OUT / name
