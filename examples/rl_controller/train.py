#!/usr/bin/env python
"""A learned controller for the virtual Omni's yaw against the classical baselines.

Trains a **residual** PPO policy on top of the best PD controller at the device's 1 kHz
(`omni_sim/OmniYaw-v0`, sine references with random frequency and amplitude), for several
training seeds, and scores it with the baselines a controls engineer tries first -- zero
command, the best P gain and the best PD gains of a grid (chosen on training-distribution
references) -- on *held-out* references (other seeds, other frequencies, random steps), each
by the same return and by the RMS tracking error in mrad.

Why PPO: the env runs at 1 kHz (thousands of steps per second of experience); PPO's updates
come once per rollout and its cost per step is one small forward pass, where SAC would do a
gradient step per env step.  Why residual: at 1 kHz an episode of 2 s is 2000 decisions and a
policy learning from scratch must first learn what a P loop already does; on top of the PD it
only has to learn the correction (its output is scaled to +-RESIDUAL_V volts, its initial mean
is ~0, so it starts as the PD).

    python examples/rl_controller/train.py                 # the committed run (~10 min, 2 cores)
    python examples/rl_controller/train.py --quick         # a smoke run (~1 min)

Writes results.json (every score, training steps, wall time, seeds, versions, env steps/s),
learning_curve.png and the results section of README.md, next to this file.
Needs `pip install ".[rl]"` (stable-baselines3 and its torch).
"""

from __future__ import annotations

import argparse
import json
import platform
import re
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
#: Held-out references: frequencies outside and between the training ones, and random steps,
#: with seeds the training never used.
HELD_OUT = ([{"reference": "sine", "frequency_hz": f, "amplitude_rad": 0.05} for f in (0.3, 1.3, 2.7, 5.0)]
            + [{"reference": "steps", "amplitude_rad": 0.05, "step_period_s": 0.5}])
HELD_OUT_SEEDS = (1001, 1002)
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
    """One episode of ``policy(obs) -> action`` on ``options``: return and RMS error [mrad].
    ``policy.residual`` (the learned one) acts through :class:`ResidualPD`, the others in volts."""
    env = gym.make(ENV_ID, **ENV_KW)
    if getattr(policy, "residual", None):
        env = ResidualPD(env, *policy.residual)
    obs, _ = env.reset(seed=seed, options=options)
    ret, err2, n, done = 0.0, 0.0, 0, False
    while not done:
        obs, r, term, trunc, info = env.step(np.array([policy(obs)], np.float32))
        ret += r
        err2 += info["tracking_error"] ** 2
        n += 1
        done = term or trunc
    env.close()
    return {"return": ret, "rms_mrad": 1e3 * float(np.sqrt(err2 / n))}


def score(policy, cases) -> dict:
    rows = [episode(policy, o, s) for o, s in cases]
    return {"return": float(np.mean([r["return"] for r in rows])),
            "rms_mrad": float(np.mean([r["rms_mrad"] for r in rows])),
            "per_case": rows}


def train_cases(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    return [({"reference": "sine", "frequency_hz": float(rng.uniform(*TRAIN_FREQ_HZ)),
              "amplitude_rad": float(rng.uniform(*TRAIN_AMP_RAD))}, 500 + i) for i in range(n)]


def held_out_cases():
    return [(o, s) for o in HELD_OUT for s in HELD_OUT_SEEDS]


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


def results_markdown(res: dict) -> str:
    """The README's results section, generated from results.json."""
    h = res["held_out"]
    rl = h["residual_ppo"]
    g = res["gains"]
    lines = [
        f"Held-out references ({len(HELD_OUT) * len(HELD_OUT_SEEDS)} episodes of "
        f"{ENV_KW['duration_s']:g} s: sines at {', '.join(str(o['frequency_hz']) for o in HELD_OUT if 'frequency_hz' in o)} Hz "
        "and random steps, seeds never used in training), mean over the episodes; the learned "
        f"controller's mean ± std over {len(res['training'])} training seeds:",
        "",
        "| controller | return | RMS tracking error [mrad] |",
        "|---|---|---|",
        f"| zero command | {h['zero']['return']:.4f} | {h['zero']['rms_mrad']:.2f} |",
        f"| best P (kp {g['best_p']['kp']:g} V/rad) | {h['best_p']['return']:.4f} | {h['best_p']['rms_mrad']:.2f} |",
        f"| best PD (kp {g['best_pd']['kp']:g} V/rad, kd {g['best_pd']['kd']:g} V s/rad) | "
        f"{h['best_pd']['return']:.4f} | {h['best_pd']['rms_mrad']:.2f} |",
        f"| residual PPO on the best PD | {rl['return_mean']:.4f} ± {rl['return_std']:.4f} | "
        f"{rl['rms_mrad_mean']:.2f} ± {rl['rms_mrad_std']:.2f} |",
        "",
        f"Verdict: {res['verdict']}",
        "",
        f"Training: {res['training'][0]['timesteps']:,} steps per seed, "
        f"{np.mean([t['wall_s'] for t in res['training']]) / 60:.1f} min per seed, "
        f"{np.mean([t['env_steps_per_s'] for t in res['training']]):,.0f} env steps/s during "
        f"training ({100 * np.mean([t['env_share_of_training'] for t in res['training']]):.0f} % of it "
        f"in the environment); whole script {res['wall_s'] / 60:.1f} min on {res['cores']} cores.",
    ]
    return "\n".join(lines)


def write_readme_section(res: dict, readme: Path) -> None:
    text = readme.read_text()
    block = re.compile(r"(<!-- results -->\n).*?(\n<!-- /results -->)", re.S)
    readme.write_text(block.sub(lambda m: m.group(1) + results_markdown(res) + m.group(2), text))


def main(argv=None) -> int:
    import os

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="training seeds")
    ap.add_argument("--timesteps", type=int, default=2_000_000, help="training steps per seed")
    ap.add_argument("--n-envs", type=int, default=8)
    ap.add_argument("--quick", action="store_true", help="a smoke run: 1 seed, 8k steps, small grids")
    ap.add_argument("--out", type=Path, default=HERE, help="folder of results.json / learning_curve.png")
    args = ap.parse_args(argv)
    if args.quick:
        args.seeds, args.timesteps = [0], 8192
    import stable_baselines3
    import torch

    t0 = time.perf_counter()
    gains = baselines(n_select=3 if args.quick else 8)
    kp, kd = gains["best_pd"]["kp"], gains["best_pd"]["kd"]
    val = train_cases(2 if args.quick else 4, seed=11)
    held = held_out_cases()[: 2 if args.quick else None]
    zero = lambda o: 0.0  # noqa: E731
    best_p = lambda o: pd_voltage(o, gains["best_p"]["kp"], 0.0)  # noqa: E731
    best_pd = lambda o: pd_voltage(o, kp, kd)  # noqa: E731
    runs = [train(s, kp, kd, args.timesteps, args.n_envs, max(args.timesteps // 8, 1024), val) for s in args.seeds]
    rl_scores = [score(r.pop("policy"), held) for r in runs]
    held_out = {"zero": score(zero, held), "best_p": score(best_p, held), "best_pd": score(best_pd, held),
                "residual_ppo": {"per_seed": rl_scores,
                                 "return_mean": float(np.mean([s["return"] for s in rl_scores])),
                                 "return_std": float(np.std([s["return"] for s in rl_scores])),
                                 "rms_mrad_mean": float(np.mean([s["rms_mrad"] for s in rl_scores])),
                                 "rms_mrad_std": float(np.std([s["rms_mrad"] for s in rl_scores]))}}
    beat = [s["rms_mrad"] < held_out["best_pd"]["rms_mrad"] and s["return"] > held_out["best_pd"]["return"]
            for s in rl_scores]
    rl = held_out["residual_ppo"]
    verdict = (f"the residual policy beats the best PD on held-out references at {sum(beat)} of "
               f"{len(beat)} training seeds (RMS {rl['rms_mrad_mean']:.2f} ± {rl['rms_mrad_std']:.2f} "
               f"against {held_out['best_pd']['rms_mrad']:.2f} mrad)")
    res = {
        "what": "residual PPO on the best PD vs zero / best P / best PD, held-out references",
        "env": {"id": ENV_ID, **ENV_KW, "train_frequency_hz": TRAIN_FREQ_HZ, "train_amplitude_rad": TRAIN_AMP_RAD,
                "held_out": HELD_OUT, "held_out_seeds": HELD_OUT_SEEDS},
        "residual_v": RESIDUAL_V, "gains": gains,
        "validation_baselines_rms_mrad": {"best_p": score(best_p, val)["rms_mrad"],
                                          "best_pd": score(best_pd, val)["rms_mrad"]},
        "training": runs, "held_out": held_out, "verdict": verdict,
        "wall_s": time.perf_counter() - t0, "cores": os.cpu_count(),
        "versions": {"python": platform.python_version(), "stable_baselines3": stable_baselines3.__version__,
                     "torch": torch.__version__, "gymnasium": gym.__version__, "numpy": np.__version__},
        "quick": args.quick,
    }
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "results.json").write_text(json.dumps(res, indent=1) + "\n")
    plot(res, args.out / "learning_curve.png")
    if args.out.resolve() == HERE:
        write_readme_section(res, HERE / "README.md")
    print(results_markdown(res))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
