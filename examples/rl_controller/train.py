#!/usr/bin/env python
"""A learned controller for the virtual Omni's yaw against the classical baselines.

Trains a **residual** PPO policy on top of the best PD controller at the device's 1 kHz
(`omni_sim/OmniYaw-v0`, sine references with random frequency and amplitude), for several
training seeds, and scores it with the baselines a controls engineer tries first -- zero
command, the best P gain and the best PD gains of a grid (chosen on training-distribution
references) -- on *held-out* references (sines below, inside and above the training band with
random phases, and random steps: 24 distinct episodes training never saw), each by the same
return and by the RMS tracking error in mrad, per reference type.

Why PPO: the env runs at 1 kHz (thousands of steps per second of experience); PPO's updates
come once per rollout and its cost per step is one small forward pass, where SAC would do a
gradient step per env step.  Why residual: at 1 kHz an episode of 2 s is 2000 decisions and a
policy learning from scratch must first learn what a P loop already does; on top of the PD it
only has to learn the correction (its output is scaled to +-RESIDUAL_V volts, its initial mean
is ~0, so it starts as the PD).

    python examples/rl_controller/train.py --quick         # a smoke run (~1 min) into ./rl_results
    python examples/rl_controller/train.py --jobs 2        # a full run into ./rl_results
    python examples/rl_controller/train.py --jobs 2 --out examples/rl_controller   # the committed record

Writes results.json (every score per held-out episode and seed, training steps, wall time, seeds,
versions, env steps/s) and learning_curve.png into ``--out`` (default ./rl_results); only with
``--out`` this folder it also rewrites the results section of README.md next to this file.
Needs `pip install ".[rl]"` (stable-baselines3 and its torch).
"""

from __future__ import annotations

import argparse
import hashlib
import importlib.util
import json
import platform
import re
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import omni_sim  # noqa: F401  (registers the environments)

HERE = Path(__file__).resolve().parent
ENV_ID = "omni_sim/OmniYaw-v0"
#: The environment as trained and scored: the device's 1 kHz loop, the encoder's quantisation
#: and the estimated velocity (what a real controller sees), the default scene.
ENV_KW = {"control_period_s": 1e-3, "quantize": True, "velocity": "estimated", "duration_s": 2.0}
#: Training references: sines, frequency and amplitude drawn per episode.
TRAIN_FREQ_HZ = (0.5, 4.0)
TRAIN_AMP_RAD = (0.02, 0.08)
#: Held-out references, a band [Hz] each: sines below, inside and above the training band, all
#: with a random phase (training sines start at phase 0 from rest at 0; these start from rest at
#: r(0)), and random steps (never in training).  N_PER_BAND episodes per band, drawn once from
#: HELD_OUT_RNG (our choice; no training draw uses it), amplitudes from the training range.  The
#: bands are our choice, around this example's first held-out set (0.3 and 5 Hz, steps every 0.5 s).
SINE_BANDS = {"low": (0.2, 0.45), "in": TRAIN_FREQ_HZ, "high": (4.5, 6.0)}
#: Random steps: a new level every step period [s] drawn from this range, levels from the env's
#: RNG seeded by HELD_OUT_STEP_SEEDS (training env seeds are 100 * seed + env index, < 1000).
STEP_PERIOD_S = (0.2, 1.0)
N_PER_BAND = 6
HELD_OUT_RNG = 2024
HELD_OUT_STEP_SEEDS = tuple(range(1001, 1001 + N_PER_BAND))
#: The bands in the README's table, with their headings.
BANDS = {"low": "sines {:g}–{:g} Hz", "in": "sines {:g}–{:g} Hz (the training band)",
         "high": "sines {:g}–{:g} Hz", "steps": "random steps"}
#: Gain grids of the baselines [V/rad], [V*s/rad]; the paper's P controller has kp = 2.
KP_GRID = (2.0, 8.0, 32.0, 128.0, 256.0, 512.0, 1024.0, 2048.0, 4096.0, 8192.0)
KD_GRID = (0.0, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0)
#: The residual's range [V] (the drive's limit is 1.3 V).
RESIDUAL_V = 0.3


# -- controllers ----------------------------------------------------------------------------------
def pd_voltage(obs, kp: float, kd: float) -> float:
    """v = kp (r - theta) - kd theta_dot (derivative on the measurement: no kick at steps)."""
    return kp * (obs[2] - obs[0]) - kd * obs[1]


class ResidualPD(gym.Wrapper):
    """The agent's action a in [-1, 1] adds ``a * RESIDUAL_V`` volts to the PD's command; it
    observes the env's observation and the reference's rate (r_k - r_{k-1}) / dt [rad/s], so it
    can learn a feedforward (the PD has none)."""

    def __init__(self, env, kp: float, kd: float):
        super().__init__(env)
        self.kp, self.kd = kp, kd
        self.action_space = gym.spaces.Box(np.float32(-1), np.float32(1), shape=(1,), dtype=np.float32)
        box = env.observation_space
        bound = 2 * float(box.high[2]) / env.unwrapped.dt
        self.observation_space = gym.spaces.Box(np.append(box.low, -bound), np.append(box.high, bound),
                                                dtype=np.float64)
        self._obs, self._r = None, 0.0

    def _with_rate(self, obs):
        rate = (obs[2] - self._r) / self.env.unwrapped.dt
        self._r = float(obs[2])
        return np.append(obs, rate)

    def reset(self, **kw):
        self._obs, info = self.env.reset(**kw)
        self._r = float(self._obs[2])
        return self._with_rate(self._obs), info

    def step(self, action):
        v = pd_voltage(self._obs, self.kp, self.kd) + RESIDUAL_V * float(np.clip(action[0], -1, 1))
        self._obs, reward, terminated, truncated, info = self.env.step(np.array([v], np.float32))
        return self._with_rate(self._obs), reward, terminated, truncated, info


class RandomSine(gym.Wrapper):
    """Each episode a sine of random frequency and amplitude (the training distribution)."""

    def reset(self, *, seed=None, options=None):
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        elif not hasattr(self, "_rng"):
            self._rng = np.random.default_rng(0)
        opts = {"reference": "sine", "frequency_hz": float(self._rng.uniform(*TRAIN_FREQ_HZ)),
                "amplitude_rad": float(self._rng.uniform(*TRAIN_AMP_RAD))}
        return self.env.reset(seed=seed, options={**opts, **(options or {})})


def episode(policy, options: dict, seed: int) -> dict:
    """One episode of ``policy(obs) -> action`` on ``options``: return, RMS error [mrad] and a
    digest of the reference it tracked.  ``policy.residual`` (the learned one) acts through
    :class:`ResidualPD`, the others in volts."""
    env = gym.make(ENV_ID, **ENV_KW)
    if getattr(policy, "residual", None):
        env = ResidualPD(env, *policy.residual)
    obs, _ = env.reset(seed=seed, options=options)
    ret, err2, refs, done = 0.0, 0.0, [], False
    while not done:
        refs.append(obs[2])
        obs, r, term, trunc, info = env.step(np.array([policy(obs)], np.float32))
        ret += r
        err2 += info["tracking_error"] ** 2
        done = term or trunc
    env.close()
    digest = hashlib.sha256(np.asarray(refs, np.float64).tobytes()).hexdigest()[:16]
    return {"return": ret, "rms_mrad": 1e3 * float(np.sqrt(err2 / len(refs))), "reference_sha256": digest}


def score(policy, cases) -> dict:
    """Mean return and RMS over ``cases`` (pairs of env options and seed) and every episode's."""
    rows = [episode(policy, o, s) for o, s in cases]
    return {"return": float(np.mean([r["return"] for r in rows])),
            "rms_mrad": float(np.mean([r["rms_mrad"] for r in rows])),
            "per_case": rows}


def train_cases(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    return [({"reference": "sine", "frequency_hz": float(rng.uniform(*TRAIN_FREQ_HZ)),
              "amplitude_rad": float(rng.uniform(*TRAIN_AMP_RAD))}, 500 + i) for i in range(n)]


def held_out_cases() -> list[dict]:
    """The held-out episodes, each a dict with its band, reference parameters and env seed."""
    rng = np.random.default_rng(HELD_OUT_RNG)
    cases = []
    for band, (f_lo, f_hi) in SINE_BANDS.items():
        for _ in range(N_PER_BAND):
            cases.append({"band": band, "reference": "sine", "frequency_hz": float(rng.uniform(f_lo, f_hi)),
                          "amplitude_rad": float(rng.uniform(*TRAIN_AMP_RAD)),
                          "phase_rad": float(rng.uniform(0.0, 2 * np.pi)), "seed": 0})
    for seed in HELD_OUT_STEP_SEEDS:
        cases.append({"band": "steps", "reference": "steps", "amplitude_rad": float(rng.uniform(*TRAIN_AMP_RAD)),
                      "step_period_s": float(rng.uniform(*STEP_PERIOD_S)), "seed": seed})
    return cases


def env_case(case: dict) -> tuple[dict, int]:
    """A held-out case as the env's (options, seed): a phase-shifted sine is an array reference
    (the env starts the yaw at rest at its first sample), steps are the env's own."""
    if case["reference"] == "sine":
        t = np.arange(int(round(ENV_KW["duration_s"] / ENV_KW["control_period_s"]))) * ENV_KW["control_period_s"]
        r = case["amplitude_rad"] * np.sin(2 * np.pi * case["frequency_hz"] * t + case["phase_rad"])
        return {"reference": r}, case["seed"]
    return ({"reference": "steps", "amplitude_rad": case["amplitude_rad"],
             "step_period_s": case["step_period_s"]}, case["seed"])


def score_held_out(policy, cases: list[dict]) -> list[dict]:
    """Every held-out episode's scores, labelled with its case's index and band."""
    rows = score(policy, [env_case(c) for c in cases])["per_case"]
    return [{"case": i, "band": c["band"], **row} for i, (c, row) in enumerate(zip(cases, rows))]


def baselines(n_select: int) -> dict:
    """Zero, best P and best PD, gains chosen by the return on training-distribution episodes."""
    sel = train_cases(n_select, seed=7)
    grid = {(kp, kd): score(lambda o, kp=kp, kd=kd: pd_voltage(o, kp, kd), sel)["return"]
            for kp in KP_GRID for kd in KD_GRID}
    best_p = max(KP_GRID, key=lambda kp: grid[(kp, 0.0)])
    best_pd = max(grid, key=grid.get)
    return {"best_p": {"kp": best_p, "kd": 0.0}, "best_pd": {"kp": best_pd[0], "kd": best_pd[1]},
            "grid_return": [[kp, kd, v] for (kp, kd), v in grid.items()], "selection_episodes": len(sel)}


# -- training -------------------------------------------------------------------------------------
def make_train_env(kp, kd, seed):
    def thunk():
        env = ResidualPD(RandomSine(gym.make(ENV_ID, **ENV_KW)), kp, kd)
        env.reset(seed=seed)
        return env
    return thunk


def train(seed: int, kp: float, kd: float, timesteps: int, n_envs: int, curve_every: int, val) -> dict:
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    torch.set_num_threads(1)
    venv = VecNormalize(DummyVecEnv([make_train_env(kp, kd, 100 * seed + i) for i in range(n_envs)]),
                        norm_obs=True, norm_reward=True, gamma=0.99)
    model = PPO("MlpPolicy", venv, n_steps=1024, batch_size=1024, n_epochs=5, learning_rate=3e-4,
                gamma=0.99, gae_lambda=0.95, clip_range=0.2, ent_coef=0.0, seed=seed, verbose=0,
                policy_kwargs={"net_arch": [64, 64], "log_std_init": -2.0}, device="cpu")

    def policy_of(model, venv):
        def act(obs):  # the agent's action in [-1, 1]; ResidualPD adds the PD
            a, _ = model.predict(venv.normalize_obs(np.asarray(obs, np.float64)[None]), deterministic=True)
            return float(a[0][0])
        act.residual = (kp, kd)
        return act

    curve, env_time, curve_time = [], [0.0], [0.0]

    class Curve(BaseCallback):
        def _on_step(self):
            if self.num_timesteps % curve_every < n_envs:
                t = time.perf_counter()
                curve.append([int(self.num_timesteps), score(policy_of(self.model, venv), val)["rms_mrad"]])
                curve_time[0] += time.perf_counter() - t
            return True

    # how much of training is the environment: time its step calls
    step_wait = venv.venv.step_wait

    def timed_step_wait():
        t = time.perf_counter()
        out = step_wait()
        env_time[0] += time.perf_counter() - t
        return out

    venv.venv.step_wait = timed_step_wait
    curve.append([0, score(policy_of(model, venv), val)["rms_mrad"]])
    t0 = time.perf_counter()
    model.learn(total_timesteps=timesteps, callback=Curve())
    wall = time.perf_counter() - t0 - curve_time[0]  # training only, not the curve's evaluations
    venv.training = False
    return {"seed": seed, "timesteps": int(model.num_timesteps), "wall_s": wall,
            "curve_evaluation_s": curve_time[0],
            "env_steps_per_s": model.num_timesteps / wall, "env_share_of_training": env_time[0] / wall,
            "curve_rms_mrad": curve, "policy": policy_of(model, venv)}


def run_seed(seed: int, kp: float, kd: float, timesteps: int, n_envs: int, val, cases) -> tuple[dict, list]:
    """Train one seed and score it on the held-out cases (in a worker process with ``--jobs``)."""
    run = train(seed, kp, kd, timesteps, n_envs, max(timesteps // 8, 1024), val)
    return run, score_held_out(run.pop("policy"), cases)


def run_seeds(seeds, jobs: int, *args) -> list[tuple[dict, list]]:
    """:func:`run_seed` for every seed, ``jobs`` at a time (each a process of one torch thread)."""
    if jobs == 1:
        return [run_seed(s, *args) for s in seeds]
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("spawn")) as pool:
        return list(pool.map(run_seed, seeds, *[[a] * len(seeds) for a in args]))


# -- writing --------------------------------------------------------------------------------------
def plot(res: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    for run in res["training"]:
        c = np.array(run["curve_rms_mrad"])
        ax.plot(c[:, 0], c[:, 1], "o-", ms=3, label=f"residual PPO, seed {run['seed']}")
    val = res["validation_baselines_rms_mrad"]
    ax.axhline(val["best_pd"], color="k", ls="--", label=f"best PD (kp {res['gains']['best_pd']['kp']:g}, "
               f"kd {res['gains']['best_pd']['kd']:g})")
    ax.axhline(val["best_p"], color="0.5", ls=":", label=f"best P (kp {res['gains']['best_p']['kp']:g})")
    ax.set(xlabel="training steps (1 ms each)", ylabel="RMS tracking error [mrad]\n(validation sines)",
           title="learning curve on training-distribution validation references")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def t_interval(x, level: float = 0.95) -> list[float]:
    """Mean of ``x`` and its Student-t interval [lo, hi] (n - 1 degrees of freedom); NaN for n < 2."""
    from scipy import stats

    x = np.asarray(x, float)
    m = float(x.mean())
    if x.size < 2:
        return [m, float("nan"), float("nan")]
    half = float(stats.t.ppf(0.5 + level / 2, x.size - 1) * x.std(ddof=1) / np.sqrt(x.size))
    return [m, m - half, m + half]


def summarize(held: dict) -> dict:
    """Per band ("all" and each of BANDS), from the per-episode rows only: each baseline's mean
    RMS [mrad] and return, the learned controller's per-seed means, their t-interval, the gain
    over the best PD (PD's RMS - PPO's, per seed) with its t-interval, and how many seeds beat it."""
    out = {}
    for band in ("all", *BANDS):
        def pick(rows, band=band):
            return [r for r in rows if band == "all" or r["band"] == band]

        row = {"episodes": len(pick(held["best_pd"]))}
        for name in ("zero", "best_p", "best_pd"):
            row[name] = {k: float(np.mean([r[k] for r in pick(held[name])])) for k in ("rms_mrad", "return")}
        ppo = [float(np.mean([r["rms_mrad"] for r in pick(rows)])) for rows in held["residual_ppo"]]
        ppo_ret = [float(np.mean([r["return"] for r in pick(rows)])) for rows in held["residual_ppo"]]
        gain = [row["best_pd"]["rms_mrad"] - x for x in ppo]
        row["residual_ppo"] = {"rms_mrad_per_seed": ppo, "rms_mrad": t_interval(ppo), "return": t_interval(ppo_ret)}
        row["gain_mrad"] = t_interval(gain)
        row["gain_rel"] = row["gain_mrad"][0] / row["best_pd"]["rms_mrad"]
        row["seeds_better"] = int(sum(g > 0 for g in gain))
        out[band] = row
    return out


def band_heading(band: str) -> str:
    lo_hi = SINE_BANDS.get(band, ())
    return BANDS[band].format(*lo_hi)


def _ci(v, fmt: str, sign: str = "") -> str:
    m, lo, hi = v
    if np.isnan(lo):
        return f"{m:{sign}{fmt}}"
    return f"{m:{sign}{fmt}} [{lo:{sign}{fmt}}, {hi:{sign}{fmt}}]"


def verdict(summary: dict, n_seeds: int) -> str:
    """Better / worse / not resolved, overall and per band, by whether the gain's interval
    excludes zero."""
    def call(band):
        _, lo, hi = summary[band]["gain_mrad"]
        return "better" if lo > 0 else "worse" if hi < 0 else "not resolved"

    a = summary["all"]
    word = {"better": "lower than", "worse": "higher than", "not resolved": "not distinguishable from"}[call("all")]
    parts = {c: [band_heading(b) for b in BANDS if call(b) == c] for c in ("better", "worse", "not resolved")}
    by_band = "; ".join(f"{c}: {', '.join(bs)}" for c, bs in parts.items() if bs)
    return (f"over all {a['episodes']} held-out episodes the residual policy's RMS error is {word} the best "
            f"PD's (gain {_ci(a['gain_mrad'], '.3f', '+')} mrad, {100 * a['gain_rel']:+.1f} %; better at "
            f"{a['seeds_better']} of {n_seeds} seeds). By reference type (the gain's 95 % interval above, "
            f"below or around zero): {by_band}.")


def results_markdown(res: dict) -> str:
    """The README's results section, generated from results.json's per-episode scores."""
    summary = summarize(res["held_out"])
    g, n = res["gains"], len(res["training"])
    cols = ["all", *BANDS]
    head = " | ".join(f"{'all' if b == 'all' else band_heading(b)} ({summary[b]['episodes']})" for b in cols)
    lines = [
        f"Held-out references: {summary['all']['episodes']} distinct episodes of {ENV_KW['duration_s']:g} s "
        "that training never saw (random frequency, amplitude 0.02–0.08 rad and phase for the sines, "
        f"random levels every {STEP_PERIOD_S[0]:g}–{STEP_PERIOD_S[1]:g} s for the steps; their parameters "
        "are in results.json). RMS tracking error [mrad], mean over each type's episodes. The learned "
        f"controller: mean over {n} training seeds and a 95 % Student-t interval over the seeds "
        f"({n - 1} degrees of freedom, of each seed's mean over the episodes: it covers the training "
        "seed's spread, the episodes are a fixed set). Gain = the best PD's RMS − the policy's.",
        "",
        f"| controller | {head} | return (all) |",
        "|---|" + "---|" * (len(cols) + 1),
    ]
    names = {"zero": "zero command", "best_p": f"best P (kp {g['best_p']['kp']:g} V/rad)",
             "best_pd": f"best PD (kp {g['best_pd']['kp']:g} V/rad, kd {g['best_pd']['kd']:g} V s/rad)"}
    for key, name in names.items():
        cells = " | ".join(f"{summary[b][key]['rms_mrad']:.2f}" for b in cols)
        lines.append(f"| {name} | {cells} | {summary['all'][key]['return']:.4f} |")
    cells = " | ".join(_ci(summary[b]["residual_ppo"]["rms_mrad"], ".2f") for b in cols)
    lines.append(f"| residual PPO on the best PD | {cells} | {_ci(summary['all']['residual_ppo']['return'], '.4f')} |")
    cells = " | ".join(f"{_ci(summary[b]['gain_mrad'], '.3f', '+')} ({100 * summary[b]['gain_rel']:+.1f} %)"
                       for b in cols)
    lines.append(f"| gain over the best PD [mrad] | {cells} | |")
    cells = " | ".join(f"{summary[b]['seeds_better']} of {n}" for b in cols)
    lines.append(f"| seeds better than the best PD | {cells} | |")
    t = res["training"]
    lines += [
        "",
        f"Verdict: {verdict(summary, n)}",
        "",
        f"Training: {t[0]['timesteps']:,} steps per seed, {np.mean([r['wall_s'] for r in t]) / 60:.1f} min per "
        f"seed, {np.mean([r['env_steps_per_s'] for r in t]):,.0f} env steps/s during training "
        f"({100 * np.mean([r['env_share_of_training'] for r in t]):.0f} % of it in the environment); whole "
        f"script {res['wall_s'] / 60:.1f} min on {res['cores']} cores shared with other work, "
        f"{res['jobs']} seeds at a time.",
    ]
    return "\n".join(lines)


def write_readme_section(res: dict, readme: Path) -> None:
    text = readme.read_text()
    block = re.compile(r"(<!-- results -->\n).*?(\n<!-- /results -->)", re.S)
    readme.write_text(block.sub(lambda m: m.group(1) + results_markdown(res) + m.group(2), text))


# -- command line ---------------------------------------------------------------------------------
class _Parser(argparse.ArgumentParser):
    """argparse with the project's one-line ``error:`` message and exit status 2."""

    def error(self, message: str) -> None:  # noqa: D401
        sys.stderr.write(f"error: {self.prog}: {message}\n")
        raise SystemExit(2)


def _int_at_least(lo: int):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
        if value < lo:
            raise argparse.ArgumentTypeError(f"must be >= {lo}, got {value}")
        return value
    return parse


def parse_args(argv=None) -> argparse.Namespace:
    """The options, checked before anything runs (bad input: one ``error:`` line, status 2)."""
    ap = _Parser(prog="train.py", description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=_int_at_least(0), nargs="+", default=[0, 1, 2, 3, 4, 5], help="training seeds")
    ap.add_argument("--timesteps", type=_int_at_least(1), default=2_000_000, help="training steps per seed")
    ap.add_argument("--n-envs", type=_int_at_least(1), default=8)
    ap.add_argument("--jobs", type=_int_at_least(1), default=1,
                    help="seeds trained at once, one process each (the committed record: 2)")
    ap.add_argument("--quick", action="store_true", help="a smoke run: 1 seed, 8k steps, fewer episodes")
    ap.add_argument("--out", type=Path, default=Path("rl_results"),
                    help="folder of results.json and learning_curve.png (default ./rl_results); "
                         "this script's own folder also rewrites its README's results section")
    args = ap.parse_args(argv)
    if len(set(args.seeds)) != len(args.seeds):
        ap.error(f"--seeds must be distinct, got {args.seeds}")
    if args.out.exists() and not args.out.is_dir():
        ap.error(f"--out {args.out} exists and is not a folder")
    if args.quick and args.out.resolve() == HERE:
        ap.error("--quick would overwrite the committed record; give another --out")
    missing = [m for m in ("stable_baselines3", "torch") if importlib.util.find_spec(m) is None]
    if missing:
        ap.error(f"{' and '.join(missing)} not installed: this example needs the rl extra, "
                 "pip install \".[rl]\" in the project's folder")
    if args.quick:
        args.seeds, args.timesteps = [0], 8192
    return args


def main(argv=None) -> int:
    import os

    args = parse_args(argv)
    import stable_baselines3
    import torch

    t0 = time.perf_counter()
    gains = baselines(n_select=3 if args.quick else 8)
    kp, kd = gains["best_pd"]["kp"], gains["best_pd"]["kd"]
    val = train_cases(2 if args.quick else 4, seed=11)
    cases = held_out_cases()
    if args.quick:  # one episode of each type
        cases = [c for i, c in enumerate(cases) if i % N_PER_BAND == 0]
    zero = lambda o: 0.0  # noqa: E731
    best_p = lambda o: pd_voltage(o, gains["best_p"]["kp"], 0.0)  # noqa: E731
    best_pd = lambda o: pd_voltage(o, kp, kd)  # noqa: E731
    held_out = {"zero": score_held_out(zero, cases), "best_p": score_held_out(best_p, cases),
                "best_pd": score_held_out(best_pd, cases)}
    digests = [r["reference_sha256"] for r in held_out["best_pd"]]
    assert len(set(digests)) == len(digests), "two held-out episodes track the same reference"
    done = run_seeds(args.seeds, args.jobs, kp, kd, args.timesteps, args.n_envs, val, cases)
    runs = [run for run, _ in done]
    held_out["residual_ppo"] = [rows for _, rows in done]
    res = {
        "what": "residual PPO on the best PD vs zero / best P / best PD, held-out references",
        "env": {"id": ENV_ID, **ENV_KW, "train_frequency_hz": TRAIN_FREQ_HZ, "train_amplitude_rad": TRAIN_AMP_RAD},
        "held_out_cases": cases, "residual_v": RESIDUAL_V, "gains": gains,
        "validation_baselines_rms_mrad": {"best_p": score(best_p, val)["rms_mrad"],
                                          "best_pd": score(best_pd, val)["rms_mrad"]},
        "training": runs, "held_out": held_out,
        "wall_s": time.perf_counter() - t0, "cores": os.cpu_count(), "jobs": min(args.jobs, len(args.seeds)),
        "versions": {"python": platform.python_version(), "stable_baselines3": stable_baselines3.__version__,
                     "torch": torch.__version__, "gymnasium": gym.__version__, "numpy": np.__version__},
        "quick": args.quick,
    }
    res["summary"] = summarize(held_out)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "results.json").write_text(json.dumps(res, indent=1) + "\n")
    plot(res, args.out / "learning_curve.png")
    if args.out.resolve() == HERE:
        write_readme_section(res, HERE / "README.md")
    print(results_markdown(res))
    print(f"wrote {args.out / 'results.json'} and {args.out / 'learning_curve.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
