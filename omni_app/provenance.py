"""What a record says of the checkout it was made from."""

from __future__ import annotations

import subprocess
from pathlib import Path

#: The checkout this package runs from (a regular install has none: :func:`git_commit` is None).
ROOT = Path(__file__).resolve().parents[1]


def _git(*args: str) -> str | None:
    """``git ARGS`` in the checkout: its output, or None outside a git checkout."""
    try:
        return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True,
                              check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return None


def git_commit(short: bool = False) -> str | None:
    """The checkout's commit (``short``: git's abbreviation; None outside a git checkout)."""
    out = _git("rev-parse", *(["--short"] if short else []), "HEAD")
    return None if out is None else out.strip()


def uncommitted(paths) -> list[str] | None:
    """The files under ``paths`` (relative to the checkout) that differ from its commit (None
    outside a git checkout)."""
    out = _git("status", "--porcelain", "--", *paths)
    return None if out is None else [ln[3:] for ln in out.splitlines() if ln.strip()]
