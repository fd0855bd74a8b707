"""The bank's studies: each runs the bank's truths through the discrepancy workflow (or beside
it) and returns its record; their scripts (``scripts/``) are thin mains and their pages are
written by :mod:`bank.writers`.  Like the library's studies (:mod:`omni_studies`) they compute
and return, and draw no figure."""
