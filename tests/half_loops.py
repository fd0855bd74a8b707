"""The third and fourth test halves' open-loop drives of a truth (tests/test_bank_test_half_3.py and
tests/test_bank_test_half_4.py): a constant command, torque off, and the speed at the end, run
through a half's own ``simulate`` (the first half's plant, control period and sub-steps)."""

from __future__ import annotations

import numpy as np

from bank.test_half import truths as tr


def constant(simulate, truth, u, seconds, theta0=0.0, sign=1.0, state=None):
    """Angle every 0.1 ms under a constant command ``sign * u`` [V] (a P law saturated at ``u``)."""
    n = int(round(seconds / tr.CONTROL_PERIOD_S))
    state = truth.initial_state() if state is None else state
    theta, cmd = simulate(truth, np.full(n, sign * 1e3), np.ones(n), 1e6, u, theta0, state)
    assert np.allclose(cmd, sign * u)
    return theta


def torque_off(simulate, truth, seconds, theta0, state=None):
    """Angle every 0.1 ms with the torque off (the winding shorted) from ``theta0`` at rest."""
    n = int(round(seconds / tr.CONTROL_PERIOD_S))
    state = truth.initial_state() if state is None else state
    theta, u = simulate(truth, np.zeros(n), np.zeros(n), 30.0, 12.0, theta0, state)
    assert np.all(u == 0.0)
    return theta


def end_speed(theta, periods=10):
    """The mean speed over the last ``periods`` control periods [rad/s]."""
    return (theta[-1] - theta[-1 - periods * tr.SUBSTEPS]) / (periods * tr.CONTROL_PERIOD_S)
