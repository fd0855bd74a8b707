"""Developer tools run from a checkout (not installed: no package of ``pyproject.toml`` lists
``tools``): :mod:`tools.docs_tables` checks the documentation's figures against their records
(the generated tables; the figures quoted in the prose, :mod:`tools.docs_claims`; the records
both read, :mod:`tools.docs_sources`)."""
