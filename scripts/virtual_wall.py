"""Render a virtual wall on the virtual Omni's yaw (omni_sim/OmniWall-v0) and plot the
penetration and the passivity observer's energy.

    python scripts/virtual_wall.py [--out virtual_wall.png] [--stiffness K] [--damping B]
                                   [--grasp loose|medium|firm] [--friction lugre|coulomb]

Draws two runs: the wall as asked, and the same wall held with no grasp damping (the hand a
bare spring) at K = 30 N*m/rad, above Colgate & Schenkel's 2 b / T = 13.9 N*m/rad for the
lugre family's b: the observer's energy into the device grows and the stylus bounces.
"""

import argparse

import gymnasium as gym
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import omni_sim  # noqa: E402,F401  (registers the environments)


def run(**kw):
    env = gym.make("omni_sim/OmniWall-v0", **kw)
    u = env.unwrapped
    env.reset(seed=0)
    t, pen, energy = [], [], []
    while True:
        _, _, term, trunc, info = env.step(u.wall_command())  # the built-in renderer
        t.append(info["time"])
        pen.append(info["penetration"])
        energy.append(info["energy"])
        if term or trunc:
            break
    env.close()
    return np.array(t), np.array(pen), np.array(energy)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="virtual_wall.png")
    p.add_argument("--stiffness", type=float, default=5.0, help="K [N*m/rad]")
    p.add_argument("--damping", type=float, default=0.002, help="B [N*m*s/rad]")
    p.add_argument("--grasp", default="medium", choices=["loose", "medium", "firm"])
    p.add_argument("--friction", default=None, choices=["lugre", "coulomb"])
    a = p.parse_args()
    runs = {f"K={a.stiffness:g}, B={a.damping:g}, {a.grasp} grasp":
                run(stiffness=a.stiffness, damping=a.damping, grasp=a.grasp, friction=a.friction),
            "K=30, B=0, bare-spring hand (no grasp damping)":
                run(stiffness=30.0, damping=0.0, grasp=(0.0, 0.0, 50.0), friction=a.friction)}
    fig, ax = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    for name, (t, pen, e) in runs.items():
        ax[0].plot(t, 1e3 * pen, label=name)
        ax[1].plot(t, 1e3 * e, label=name)
    ax[0].axhline(0, color="k", lw=0.6)
    ax[0].set_ylabel("penetration [mrad]")
    ax[1].set_ylabel("observer: energy into\nthe device [mJ]")
    ax[1].set_xlabel("t [s]")
    ax[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)
    print(f"wrote {a.out}")
    for name, (t, pen, e) in runs.items():
        print(f"{name}: final penetration {1e3 * pen[-1]:.3f} mrad, observer energy {1e3 * e[-1]:.4f} mJ")


if __name__ == "__main__":
    main()
