"""Render a short rollout of the virtual Omni (P controller, kp = 2 V/rad) as PNG frames.

Headless: picks ``MUJOCO_GL=egl`` when no display is set (override with ``MUJOCO_GL=osmesa``),
before mujoco is imported.  Frames are written with matplotlib (``plt.imsave``), no imageio.

    python scripts/render_rollout.py [--out docs/rollout] [--frames 8] [--duration 1.0]
                                     [--pose 65 90] [--still docs/reference/env_render.png]

``--still PATH`` also writes the first frame (the arm at rest in the requested pose) to PATH;
``docs/reference/env_render.png`` in the README was made with the defaults.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "egl"  # must precede the first import of mujoco

import gymnasium as gym  # noqa: E402
import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import omni_sim  # noqa: E402,F401  (registers omni_sim/OmniYaw-v0)

KP = 2.0  # [V/rad], the paper's yaw gain


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("docs/rollout"),
                        help="folder for frame_NNN.png (created)")
    parser.add_argument("--frames", type=int, default=8, help="number of frames")
    parser.add_argument("--duration", type=float, default=1.0, help="rollout length [s]")
    parser.add_argument("--pose", nargs=2, type=float, default=(65.0, 90.0),
                        metavar=("GAMMA1_DEG", "GAMMA2_DEG"), help="arm set points [deg]")
    parser.add_argument("--size", nargs=2, type=int, default=(640, 480),
                        metavar=("WIDTH", "HEIGHT"), help="image size [px]")
    parser.add_argument("--still", type=Path, default=None,
                        help="also write the first frame to this PNG")
    args = parser.parse_args(argv)
    if args.frames < 1 or not args.duration > 0:
        print("error: --frames must be >= 1 and --duration > 0", file=sys.stderr)
        return 2

    env = gym.make("omni_sim/OmniYaw-v0", render_mode="rgb_array", render_width=args.size[0],
                   render_height=args.size[1], gamma1_set_deg=args.pose[0],
                   gamma2_set_deg=args.pose[1], reference="sine", frequency_hz=1.5,
                   amplitude_rad=0.5, duration_s=args.duration)
    try:
        obs, _ = env.reset(seed=0)
        frame = env.render()
    except Exception as exc:  # no GL backend: say how to get one
        print(f"error: rendering failed ({exc}); try MUJOCO_GL=egl or MUJOCO_GL=osmesa",
              file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    if args.still is not None:
        args.still.parent.mkdir(parents=True, exist_ok=True)
        plt.imsave(args.still, frame)
        print(f"wrote {args.still}")
    n_steps = int(round(args.duration / env.unwrapped.dt))
    every = max(1, n_steps // args.frames)
    vmax = env.unwrapped.voltage_limit
    written = 0
    for k in range(n_steps + 1):
        if k % every == 0 and written < args.frames:
            path = args.out / f"frame_{written:03d}.png"
            plt.imsave(path, frame if k == 0 else env.render())
            written += 1
        if k == n_steps:
            break
        v = min(max(KP * (obs[2] - obs[0]), -vmax), vmax)
        obs, _, _, truncated, _ = env.step(np.array([v]))
    env.close()
    print(f"wrote {written} frames to {args.out}/ (every {every * env.unwrapped.dt:g} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
