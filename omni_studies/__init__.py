"""Studies of the virtual Omni: the floor between the simulator (:mod:`omni_sim`) and the
command line (:mod:`omni_app`).

A study computes and returns its results; writing records and drawing figures is
:mod:`omni_app`'s, and ``scripts/`` are the thin mains that run a study and write its record.

* :mod:`omni_studies.calibration`: the virtual Omni calibrated to the paper's tables (targets,
  parameters, the fit, the MJCF/campaign/record writers it owns);
* :mod:`omni_studies.fidelity`: the table-level search for the effect the calibration lacks,
  and the matched scene it writes;
* :mod:`omni_studies.comparison`: the friction families' figures beside the paper's;
* :mod:`omni_studies.zwidth`: which virtual walls the yaw renders passively (the energy test).
"""
