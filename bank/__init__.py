"""The validation bank of the discrepancy workflow (``omni discrepancy``): truths written
independently of the effect library, the hidden-effect cases, the coverage study's ranges, the
studies that run them and their writers; the test half (truths written from the literature by
someone who did not read the library).  A distribution of its own (``omni-alpha-bank``,
``bank/pyproject.toml``), installed from the source checkout beside the library
(``pip install -e ".[test]" -e ./bank``) and never shipped with it; ``bank/README.md``.

Modules: :mod:`.omni_truths` (the truth writers on the virtual Omni), :mod:`.servo_truth` (the
geared-servo pendulum's truth, a simulation of its own), :mod:`.hidden` (the cases, their data,
the pass criteria), :mod:`.ranges` (the coverage study's magnitudes); :mod:`.studies` (compute
and return), :mod:`.writers` (records, pages, figures); :mod:`.test_half`.
"""
