"""Check the results tables and quoted figures of README.md and docs/**/*.md against the records
they summarise (:mod:`tools.docs_tables`); ``--write`` rewrites the generated tables.

    python scripts/docs_tables.py            # check: list what drifted, exit status 1 if any
    python scripts/docs_tables.py --write    # rewrite the generated tables in docs/**/*.md

The tool lives in the checkout's ``tools/`` folder, which is not installed (only developers run
it); this script runs that file as the main program (``python -m tools.docs_tables`` from the
checkout's root does the same).
"""

import runpy
from pathlib import Path

TOOL = Path(__file__).resolve().parents[1] / "tools" / "docs_tables.py"

if __name__ == "__main__":
    runpy.run_path(str(TOOL), run_name="__main__")
