"""What a record says of the checkout it was made from."""

from __future__ import annotations

import subprocess
from pathlib import Path

#: The checkout this package runs from (a regular install has none: :func:`git_commit` is None).
ROOT = Path(__file__).resolve().parents[1]


def git_commit() -> str | None:
    """The checkout's commit (None outside a git checkout)."""
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True,
                              text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None
