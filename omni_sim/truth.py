"""Ground truth of the virtual Omni, for checking what the identification finds.

Unlike the paper we know the plant: MuJoCo's mass matrix gives the true yaw inertia, and the
model's damping, torque constant and gain give the true linear coefficients.  This module turns
them into the quantities the paper's method estimates.

Linear truth of a sampled P loop
--------------------------------
Without friction the yaw axis is ``I theta'' + c theta' = beta_bar v`` (3), i.e. (4) with
``C = c/I`` and ``beta_tilde = beta_bar/I``.  The Omni's controller samples theta every
``T = 1 ms`` and holds ``v_k = kp (r_k - theta_k)`` (zero-order hold).  That loop is not exactly
(13): the hold acts like a delay of about ``T/2`` and lowers the apparent damping by about
``beta T/2`` (~0.3 1/s here, 5-10 %).  :func:`sampled_linear_truth` therefore computes the
*exact* steady-state sine response of the sampled loop (ZOH discretisation of (4), closed with
the sampled P law, evaluated on the unit circle) at the campaign's frequencies and passes it
through the same global fit (22) as the data.  The continuous values ``c/I`` and
``kp beta_bar / I`` are reported beside it.
"""

from __future__ import annotations

import math

import numpy as np

from . import experiments as ex
from .device import Device


def yaw_dynamics(device: Device, gamma1_deg: float, gamma2_deg: float) -> dict:
    """True yaw-axis constants of ``device`` at an actual pose.

    Returns
    -------
    dict
        ``inertia`` [kg*m^2] (mass matrix, armature included), ``damping`` c [N*m*s/rad],
        ``frictionloss`` [N*m], ``lugre_sigma0`` [N*m/rad], ``lugre_Fc``, ``lugre_Fs`` [N*m]
        (:meth:`omni_sim.device.Device.friction`), ``beta_bar`` [N*m/V], ``C`` = c/I [1/s],
        ``beta_tilde`` = beta_bar/I [rad/(V*s^2)], ``I_paper`` = I/beta_bar (the paper's units).
    """
    inertia = device.inertia(gamma1_deg, gamma2_deg)
    damping = device.yaw_damping
    beta_bar = device.torque_constant
    return {
        "inertia": inertia,
        "damping": damping,
        **device.friction(),
        "beta_bar": beta_bar,
        "C": damping / inertia,
        "beta_tilde": beta_bar / inertia,
        "I_paper": inertia / beta_bar,
    }


def zoh_discretise(a: np.ndarray, b: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(A_d, B_d) of x' = a x + b u with u held over ``dt``: the matrix exponential of
    [[a, b], [0, 0]]·dt, exactly as ``scipy.signal.cont2discrete((a, b, c, d), dt, "zoh")``
    computes it (the same numbers; scipy.signal itself takes ~1 s to import)."""
    em = np.vstack((np.hstack((a, b)),
                    np.hstack((np.zeros((b.shape[1], a.shape[0])), np.zeros((b.shape[1], b.shape[1]))))))
    from scipy import linalg  # here: importing scipy.linalg costs every command ~0.15 s

    ms = linalg.expm(dt * em)[:a.shape[0], :]
    return ms[:, 0:a.shape[1]], ms[:, a.shape[1]:]


def _discrete_plant(C: float, beta_tilde: float, period_s: float,
                    physics_step_s: float | None) -> tuple[np.ndarray, np.ndarray]:
    """State-space (A, B) over one control period of (4) with the command held.

    ``physics_step_s=None``: exact zero-order-hold discretisation.  Otherwise the plant as
    MuJoCo's ``implicitfast`` integrator steps it (semi-implicit Euler, damping implicit):
    ``(1 + h C) w' = w + h beta_tilde v``, ``theta' = theta + h w'``, repeated
    ``period_s / h`` times.
    """
    if physics_step_s is None:
        a = np.array([[0.0, 1.0], [0.0, -C]])
        b = np.array([[0.0], [beta_tilde]])
        return zoh_discretise(a, b, period_s)
    h = physics_step_s
    n = int(round(period_s / h))
    k = 1.0 / (1.0 + h * C)
    a_h = np.array([[1.0, h * k], [0.0, k]])
    b_h = np.array([[h * h * k * beta_tilde], [h * k * beta_tilde]])
    ad, bd = np.eye(2), np.zeros((2, 1))
    for _ in range(n):
        ad, bd = a_h @ ad, a_h @ bd + b_h
    return ad, bd


def sampled_sine_response(C: float, beta_tilde: float, kp: float, frequencies_hz,
                          period_s: float, physics_step_s: float | None = None) -> np.ndarray:
    """Exact steady-state gain ``theta/r`` (complex) of the sampled P loop at each frequency.

    Plant (4) ``theta'' + C theta' = beta_tilde v`` discretised over the control period
    ``period_s`` (see :func:`_discrete_plant`); loop ``v_k = kp (r_k - theta_k)``;
    ``r_k = A_r sin(w k T)``; gain evaluated at ``z = exp(i w T)``.
    """
    ad, bd = _discrete_plant(C, beta_tilde, period_s, physics_step_s)
    c = np.array([[1.0, 0.0]])
    a_cl = ad - kp * bd @ c
    out = []
    for f in np.atleast_1d(np.asarray(frequencies_hz, dtype=float)):
        z = np.exp(1j * 2 * np.pi * f * period_s)
        out.append((c @ np.linalg.solve(z * np.eye(2) - a_cl, kp * bd))[0, 0])
    return np.array(out)


def sampled_linear_truth(C: float, beta_tilde: float, kp: float, frequencies_hz,
                         period_s: float, physics_step_s: float | None = None,
                         amplitude_rad: float = 1.0) -> tuple[float, float]:
    """(C_linear, beta_linear) that (22) returns for the exact sampled loop's sine responses.

    The fit (22) is applied to the response at the sample instants ``t_k = k T``: with
    ``r = A_r sin(wt) = Im(A_r e^{iwt})``, ``theta = Im(h A_r e^{iwt})``, so in (14)
    ``A1 = A_r Im(h)`` and ``A2 = A_r Re(h)``.
    """
    from identification.linear import global_coefficients

    h = sampled_sine_response(C, beta_tilde, kp, frequencies_hz, period_s,
                              physics_step_s) * amplitude_rad
    A1, A2 = h.imag, h.real
    w = 2 * math.pi * np.asarray(frequencies_hz, dtype=float)
    return global_coefficients(A1, A2, np.full_like(w, amplitude_rad), w)


def inertia_truth(device: Device, inertia_params, poses=None, fitted_poses=None) -> dict:
    """Identified inertia (6) x beta_bar vs MuJoCo's yaw inertia at the actual (sagged) poses of
    ``device``.

    ``poses``: set points [deg] to check (default: Table 2's); ``fitted_poses``: those the
    identification saw (default: Table 1's).
    """
    poses = ex.TABLE2_POSES if poses is None else poses
    fitted_poses = ex.TABLE1_POSES if fitted_poses is None else fitted_poses
    beta_bar = device.torque_constant
    rows = []
    for g1s, g2s in poses:
        g1, g2 = device.equilibrium(g1s, g2s)
        true = device.inertia(g1, g2)
        pred = float(inertia_params.inertia(g1, g2)) * beta_bar
        rows.append({"gamma1_set_deg": g1s, "gamma2_set_deg": g2s, "gamma1_deg": g1,
                     "gamma2_deg": g2, "true_kg_m2": true, "identified_kg_m2": pred,
                     "rel_error": pred / true - 1, "fitted_pose": (g1s, g2s) in fitted_poses})
    errs = np.abs([r["rel_error"] for r in rows])
    unseen = np.abs([r["rel_error"] for r in rows if not r["fitted_pose"]])
    return {"max_rel_error": float(errs.max()), "mean_abs_rel_error": float(errs.mean()),
            "max_rel_error_unseen_poses": float(unseen.max()) if unseen.size else None,
            "n_poses": len(rows), "n_unseen_poses": int(unseen.size),
            "beta_bar_N_m_per_V": beta_bar, "poses": rows}


def linear_truth(device: Device, ident) -> list[dict]:
    """Identified C_linear, beta_linear per pose vs the device's true (continuous) values."""
    rows = []
    for p in ident.poses:
        d = yaw_dynamics(device, p.gamma1_deg, p.gamma2_deg)
        rows.append({"gamma1_deg": p.gamma1_deg, "gamma2_deg": p.gamma2_deg,
                     "C_linear": p.C_linear, "C_true": d["C"],
                     "beta_linear": p.beta_linear, "beta_true": p.kp * d["beta_tilde"]})
    return rows
