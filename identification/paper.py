"""The paper's published numbers, read from ``identification/data/*.csv`` (one home for them).

Every table is stored as printed (provenance and inconsistencies: ``data/README.md`` and
``data/REPRODUCTION.md``); nothing else in the project writes the paper's numbers again.
"""

from __future__ import annotations

import csv
from functools import lru_cache
from importlib import resources

#: The paper's step-response headline: its "Medians" row ratio (a ratio of means, see data/README).
PAPER_STEP_RATIO = 2.6


@lru_cache(maxsize=None)
def _rows(name: str) -> tuple[dict, ...]:
    text = resources.files("identification").joinpath("data", name).read_text()
    out = []
    for row in csv.DictReader(text.splitlines()):
        rec = {}
        for k, v in row.items():
            try:
                rec[k] = float(v)
            except ValueError:
                rec[k] = v
        out.append(rec)
    return tuple(out)


def table(name: str) -> list[dict]:
    """Rows of ``identification/data/<name>`` as dicts (numbers as float, labels as str)."""
    return [dict(r) for r in _rows(name)]
