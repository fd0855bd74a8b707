"""The held-out folds' fits (discrepancy.folds.fit_folds): each fold converges on its own
training samples from a start that saw none of its held-out ones, and its held-out samples
cannot move it.

Truth: the bank's hidden viscous damping (written by the bank's truth model, independently of
the library), exact encoder, so every fold's training optimum is the hidden value itself."""

import dataclasses

import mujoco
import numpy as np

from omni_sim import model as om
from omni_sim.device import Device
from discrepancy import effects as fx
from bank import hidden
from discrepancy import experiment_set
from discrepancy.fit import Problem
from discrepancy.folds import block_folds, fit_folds
from discrepancy.replay import Replayer, prepare_runs


def _data():
    case = hidden.case("viscous_damping")
    exps = experiment_set.experiments(poses=((65.0, 90.0),), frequencies_hz=(1.5,), amplitudes_rad=(0.15,),
                                      step_amplitudes_rad=(0.2,), duration_s=1.0)
    spec = mujoco.MjSpec.from_file(str(om.DEFAULT_SCENE))
    runs = prepare_runs(hidden.generate(case, exps, exact=True, jobs=1), Device(spec.compile()))
    return spec, runs, case.effects[0][1][0]


def test_every_fold_converges_to_the_hidden_value_from_the_users_value():
    spec, runs, truth = _data()
    builder = fx.ModelBuilder(spec)
    eff = builder.effect("viscous_damping")
    folds = block_folds(runs, 3)
    with Replayer(1) as rep:
        prob = Problem(builder, [], [eff], runs, rep)
        start = builder.nominal_values(eff)
        assert abs(start[0] - truth) > 0.2 * truth  # the user's value is well off
        xs = fit_folds(prob, folds, [start] * len(folds))
    for x in xs:
        # exact data of a law the library writes the same way: the training optimum is the
        # truth; 1e-3 of it is the trust-region fit's step test's reach (it stops when a step is
        # below xtol = 1e-3 of the parameter, and a Gauss-Newton step on exact data of one
        # smooth parameter leaves far less than its own length to go)
        assert abs(x[0] - truth) <= 1e-3 * truth, (x, truth)


def test_a_folds_held_out_samples_cannot_move_its_fit():
    spec, runs, _ = _data()
    builder = fx.ModelBuilder(spec)
    eff = builder.effect("viscous_damping")
    folds = block_folds(runs, 3)
    start = builder.nominal_values(eff)
    with Replayer(1) as rep:
        clean = fit_folds(Problem(builder, [], [eff], runs, rep), folds, [start] * 3)
        # fold 1's held-out block replaced by garbage in every run: fold 1's fit must not change
        spoiled = []
        for r, h in zip(runs, folds[1].held):
            theta = r.theta.copy()
            theta[h] += 0.3 * np.sin(np.arange(h.sum()))
            spoiled.append(dataclasses.replace(r, theta=theta))
        dirty = fit_folds(Problem(builder, [], [eff], spoiled, rep), folds, [start] * 3)
    np.testing.assert_array_equal(dirty[1], clean[1])
    assert not np.array_equal(dirty[0], clean[0])  # the other folds train on that block: they move
