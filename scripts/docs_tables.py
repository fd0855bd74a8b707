"""Check the results tables and quoted figures of README.md and docs/**/*.md against the records
they summarise (:mod:`omni_app.docs_tables`); ``--write`` rewrites the generated tables.

    python scripts/docs_tables.py            # check: list what drifted, exit status 1 if any
    python scripts/docs_tables.py --write    # rewrite the generated tables in docs/**/*.md
"""

from omni_app.docs_tables import main

if __name__ == "__main__":
    raise SystemExit(main())
