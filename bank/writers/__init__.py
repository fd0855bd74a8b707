"""The writers of the bank's studies: their records and pages under ``docs/studies/discrepancy/``
and their figures (as :mod:`omni_app` writes the library's)."""
