"""Developer tools run from a checkout (not installed: no package of ``pyproject.toml`` lists
``tools``): :mod:`tools.docs_tables` checks the documentation's figures against their records."""
