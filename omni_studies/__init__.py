"""Studies of the virtual Omni: the floor between the simulator (:mod:`omni_sim`) and the
command line (:mod:`omni_app`).

A study computes and returns its results; writing pages and drawing figures is
:mod:`omni_app`'s, and ``scripts/`` are the thin mains that run a study and write its record.
docs/reference/architecture.md lists every study (reproduce, sweep, calibration, fidelity,
the fidelity screen and the alpha verdict, comparison, friction_study, the Z-width studies)
and what it may import.  The validation bank's studies are the bank's (``bank.studies``, a
distribution of its own); :mod:`.bank_link` is the one door to the bank's cases.
"""
