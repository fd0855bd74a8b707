"""Where a load law's closed-loop optimum lies on the user's pendulum (the first test half's
``i_users_pendulum``, spent, so development data), fitted with ``load_friction``'s form (a
Coulomb level ``Fc + mu |tau_m|`` that sticks) and with the same law behind a smooth sign
(``mu |tau_m| tanh(w / w_s)``, no stick, as the truth's own law).  The question came from the
library's fits of this case, whose gear came out above the truth with the coefficients apart;
the record answers it near the truth only (docs/method/discrepancy.md, "A load law that sticks,
beside one behind a smooth sign"): it does not show why the sticking form's fit goes where it
goes.

:func:`record` replays every run of the case in one plain per-step loop (the model file's
constants as the parameters say, MuJoCo's ``mj_step`` at the 1 ms control period, the P law
``clip(kp (r - y), +-limit)`` on the quantised encoder, the logged goal held from the first
period at or after its log time, ``bank.servo_truth.held_index``), with the load law applied
either as ``load_friction`` writes it (the stick level ``dof_frictionloss = Fc + mu |tau_m|``,
``mu`` passing from ``mu_back`` to ``mu_drive`` over ``LOAD_FRICTION_BLEND_RAD_S`` as
:mod:`omni_sim.device.laws` blends it) or as the truth writes it (the smooth force
``-L tanh(w / w_s)``, ``L = mu |tau_m|`` with ``mu = mu_drive`` when ``tau_m w > 0`` else
``mu_back``, linearly implicit: its slope added to the joint's damping, as
``bank.servo_truth.simulate_efficiency`` applies its loss); ``tau_m = gear u - b_emf w``.  For each form it fits the eight
parameters (armature, damping, Coulomb level, gear, mu_drive, mu_back, b_emf, and ``w_s`` for
the smooth form) by ``scipy.optimize.least_squares`` on the angle residual at the log times,
from two starts fixed before the run: the truth, and the nominal file's values with mu 0.1 in
both quadrants, b_emf 0 and w_s 0.05 rad/s.  The residual is every run's, none held out: the
question is where each form's optimum lies, not how well it predicts.

Not the library's replay (``discrepancy.replay``) nor its fit: a loop small enough to read
whole, so that the two forms differ in the law alone.  Deterministic; about 10 min on 2 cores.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import mujoco
import numpy as np
from scipy.optimize import least_squares

from bank.servo_truth import held_index, read_encoder
from identification.dataset import read_dataset
from omni_sim.device.laws import LOAD_FRICTION_BLEND_RAD_S

#: The fitted parameters, in order, their scales (the fit's units) and bounds.
PARAMS = ("armature_kgm2", "damping_nms_per_rad", "frictionloss_nm", "gear_nm_per_v",
          "mu_drive", "mu_back", "b_emf_nms_per_rad", "w_s_rad_s")
SCALE = np.array([1e-3, 0.1, 0.01, 0.1, 0.1, 0.1, 0.1, 0.01])
LOWER = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.001])
UPPER = np.array([0.01, 1.1, 0.3, 5.0, 1.0, 1.0, 5.0, 1.0])
#: The far start (the nominal file's constants; the law's coefficients at a guess).
NOMINAL_START = {"armature_kgm2": 2.5e-3, "damping_nms_per_rad": 0.37, "frictionloss_nm": 0.03,
                 "gear_nm_per_v": 0.3, "mu_drive": 0.1, "mu_back": 0.1, "b_emf_nms_per_rad": 0.0,
                 "w_s_rad_s": 0.05}
#: Evaluations per fit at most.
MAX_NFEV = 60


def truth_values(case: dict) -> dict:
    """The case's true values of :data:`PARAMS` (its ``cases.json`` entry: the perturbed
    plant, the law's mu and w0)."""
    p, q = case["plant"], case["params"]
    return {"armature_kgm2": p["armature"], "damping_nms_per_rad": p["emf"] + p["bearing"],
            "frictionloss_nm": p["coulomb"], "gear_nm_per_v": p["gear"], "mu_drive": q["mu"],
            "mu_back": q["mu"], "b_emf_nms_per_rad": p["emf"], "w_s_rad_s": q["w0"]}


class Replay:
    """The runs of one case replayed on the model file with the load law in one form."""

    def __init__(self, model_path: str | Path, runs: list, smooth: bool):
        self.spec = mujoco.MjSpec.from_file(str(model_path))
        self.runs, self.smooth = runs, smooth

    def residual(self, x: np.ndarray) -> np.ndarray:
        """The angle residuals [rad] of every run at its log times, concatenated."""
        arm, damp, fl, gear, mu_d, mu_b, b_emf, w_s = (float(v) for v in x)
        spec = self.spec.copy()
        j = spec.joints[0]
        j.armature, j.frictionloss = arm, fl
        j.damping[0] = damp
        spec.actuators[0].gear[0] = gear
        m = spec.compile()
        d = mujoco.MjData(m)
        out = []
        for run in self.runs:
            mujoco.mj_resetData(m, d)
            out.append(self._run(m, d, run, (damp, fl, gear, mu_d, mu_b, b_emf, w_s)))
        return np.concatenate(out)

    def _run(self, m, d, run, law) -> np.ndarray:
        damp, fl, gear, mu_d, mu_b, b_emf, w_s = law
        dt = float(m.opt.timestep)
        t_log = np.asarray(run.t, float)
        n = math.floor(t_log[-1] / dt + 1e-9) + 1
        t = np.arange(n + 1) * dt
        hold = held_index(t_log, t[:n])
        goal, on = np.asarray(run.r, float)[hold], np.asarray(run.enabled)[hold] != 0
        kp, limit, step = run.meta["kp"], run.meta["command_limit"], run.meta["encoder_step_rad"]
        d.qpos[0] = run.theta[0]
        mujoco.mj_forward(m, d)
        theta = np.empty(n + 1)
        theta[0] = d.qpos[0]
        for k in range(n):
            y = read_encoder(theta[k], 0.0, step)
            u = min(max(kp * (goal[k] - y), -limit), limit) if on[k] else 0.0
            w = float(d.qvel[0])
            tau_m = gear * u - b_emf * w
            if self.smooth:  # the truth's own form: the quadrant's coefficient, a smooth sign
                level = (mu_d if tau_m * w > 0 else mu_b) * abs(tau_m)
                th = math.tanh(w / w_s)
                slope = level * (1.0 - th * th) / w_s
                m.dof_damping[0] = damp + slope
                d.qfrc_applied[0] = -level * th + slope * w
            else:  # load_friction's: the coefficient blended over LOAD_FRICTION_BLEND_RAD_S
                s = 0.5 * (1.0 + math.tanh(math.copysign(1.0, tau_m) * w / LOAD_FRICTION_BLEND_RAD_S))
                m.dof_frictionloss[0] = fl + (mu_b + (mu_d - mu_b) * s) * abs(tau_m)
            d.ctrl[0] = u
            mujoco.mj_step(m, d)
            theta[k + 1] = d.qpos[0]
        return np.interp(t_log, t, theta) - np.asarray(run.theta, float)


def _rms(r: np.ndarray) -> float:
    return float(np.sqrt(np.mean(r * r)))


def fit(replay: Replay, start: dict) -> dict:
    """A least-squares fit of :data:`PARAMS` (the stick form's ``w_s`` held) from ``start``."""
    x0 = np.array([start[p] for p in PARAMS])
    free = np.ones(len(PARAMS), bool)
    free[-1] = replay.smooth

    def res(z):
        x = x0.copy()
        x[free] = z * SCALE[free]
        return replay.residual(x)

    sol = least_squares(res, x0[free] / SCALE[free], diff_step=1e-3, max_nfev=MAX_NFEV,
                        bounds=(LOWER[free] / SCALE[free], UPPER[free] / SCALE[free]))
    x = x0.copy()
    x[free] = sol.x * SCALE[free]
    return {"start_rms_rad": _rms(res(x0[free] / SCALE[free])), "rms_rad": _rms(sol.fun),
            "nfev": int(sol.nfev), "values": dict(zip(PARAMS, x.tolist()))}


def record(case_dir: str | Path, cases_json: str | Path, model_path: str | Path,
           progress=print) -> dict:
    """The record (``smooth_sign.json``): the truth, and for each form its residual at the
    truth and its fits from the two starts."""
    case_dir = Path(case_dir)
    case = next(c for c in json.loads(Path(cases_json).read_text())["cases"] if c["name"] == case_dir.name)
    truth = truth_values(case)
    runs = read_dataset(case_dir, require_pose=False, uniform=False)
    out = {"case": case["name"], "law": case["equation"], "seed": case["seed"], "truth": truth,
           "settings": {"max_nfev": MAX_NFEV, "starts": ["truth", "nominal"], "nominal_start": NOMINAL_START},
           "forms": {}}
    for form in ("stick", "smooth"):
        rep = Replay(model_path, runs, smooth=form == "smooth")
        entry = {"rms_at_truth_rad": _rms(rep.residual(np.array([truth[p] for p in PARAMS])))}
        for name, start in (("truth", truth), ("nominal", NOMINAL_START)):
            entry[f"fit_from_{name}"] = fit(rep, start)
            progress(f"{form} from {name}: rms {entry[f'fit_from_{name}']['rms_rad']:.3e} rad")
        out["forms"][form] = entry
    return out
