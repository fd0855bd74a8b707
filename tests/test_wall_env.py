"""omni_sim/OmniWall-v0: a virtual wall on the yaw, pushed by a hand model."""

import json
import subprocess
import sys
import textwrap

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import omni_sim  # noqa: F401
from omni_sim.env import InvalidOptionError
from omni_sim.wall_env import GRASPS, TIP_RADIUS_M, OmniWallEnv
from test_env import headless_env, run_headless_check

WALL_ID = "omni_sim/OmniWall-v0"


def _run(env, n=None, seed=0):
    u = env.unwrapped
    env.reset(seed=seed)
    out = []
    for _ in range(n or u.n):
        obs, r, te, tr, info = env.step(u.wall_command())
        out.append((obs.copy(), r, info["energy"], info["penetration"]))
        if te or tr:
            break
    return out


def test_check_env_and_registration():
    env = gym.make("omni_sim/OmniWall-v0")
    # the render modes: headless in a subprocess (test_check_env_headless_tries_every_mode)
    check_env(env.unwrapped, skip_render_check=True)


@pytest.mark.parametrize("mujoco_gl", [None, "egl"], ids=["MUJOCO_GL-unset", "egl"])
def test_check_env_headless_tries_every_mode(mujoco_gl):
    """gymnasium's full check_env without a display, render modes included (as OmniYaw-v0's):
    with MUJOCO_GL=egl it renders rgb_array; "human" is refused when made, with a reason."""
    run_headless_check(WALL_ID, mujoco_gl)


def test_human_mode_needs_a_display(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(InvalidOptionError, match="needs a display"):
        OmniWallEnv(render_mode="human")
    monkeypatch.setenv("DISPLAY", ":0")
    assert "human" in OmniWallEnv().metadata["render_modes"]


#: Renders the wall env (argv: output prefix) with the stylus at two start angles, 0.6 rad apart,
#: and at a smaller size; exit 77 when MUJOCO_GL=egl cannot make a context.
_RENDER = textwrap.dedent("""
    import json, sys
    import mujoco
    import numpy as np
    try:
        mujoco.GLContext(8, 8).free()
    except Exception as exc:
        print(repr(exc), file=sys.stderr)
        sys.exit(77)
    import gymnasium as gym
    out = {}
    for start, size in ((-0.6, (640, 480)), (0.0, (640, 480)), (0.0, (320, 240))):
        env = gym.make("omni_sim:omni_sim/OmniWall-v0", render_mode="rgb_array", start_rad=start,
                       render_width=size[0], render_height=size[1])
        env.reset(seed=0)
        img = env.render()
        key = f"{start:g}_{size[0]}"
        np.save(f"{sys.argv[1]}_{key}.npy", img)
        out[key] = dict(shape=list(img.shape), dtype=str(img.dtype), std=float(img.std()))
        env.close()
    print(json.dumps(out))
""")


def test_render_rgb_array_with_egl(tmp_path):
    """MUJOCO_GL=egl, no display: rgb_array gives an image of the asked size, not blank, that
    follows the stylus's yaw (skipped only where EGL cannot make a context)."""
    proc = subprocess.run([sys.executable, "-c", _RENDER, str(tmp_path / "img")],
                          capture_output=True, text=True, timeout=300, env=headless_env("egl"))
    if proc.returncode == 77:
        pytest.skip(f"EGL cannot make an OpenGL context here: {proc.stderr.strip()[-300:]}")
    assert proc.returncode == 0, proc.stderr[-2000:]
    res = json.loads(proc.stdout.strip().splitlines()[-1])
    assert res["-0.6_640"]["shape"] == res["0_640"]["shape"] == [480, 640, 3]
    assert res["0_320"]["shape"] == [240, 320, 3]
    for key, r in res.items():
        assert r["dtype"] == "uint8" and r["std"] > 10, (key, r)  # not a blank image
    a, b = (np.load(tmp_path / f"img_{k}.npy") for k in ("-0.6_640", "0_640"))
    assert np.mean(np.any(a != b, axis=2)) > 0.005  # the stylus turned 0.6 rad


def test_seeded_episode_is_deterministic():
    a = _run(gym.make("omni_sim/OmniWall-v0", friction="coulomb", duration_s=0.3))
    b = _run(gym.make("omni_sim/OmniWall-v0", friction="coulomb", duration_s=0.3))
    assert all(np.array_equal(x[0], y[0]) and x[1:] == y[1:] for x, y in zip(a, b))


def test_hand_push_settles_at_the_spring_balance():
    """Ideal-ish check: with the renderer, the hand spring k_h (push p behind the wall) and the
    wall spring K balance at penetration k_h p / (k_h + K) (exact encoder, no dry friction)."""
    env = OmniWallEnv(quantize=False, stiffness=5.0, damping=0.002, duration_s=2.0)
    env.device.scale_friction(0.0)
    pen = _run(env)[-1][3]
    k_h = GRASPS["medium"][2] * TIP_RADIUS_M ** 2
    assert pen == pytest.approx(k_h * 0.02 / (k_h + 5.0), rel=1e-3)


def test_observer_sign_passive_and_active_wall():
    """Passive wall: the observer's energy into the device never exceeds what the wall's spring
    stores (1/2 K pen^2), ends negative (the wall absorbed energy) and the oscillation decays.
    Without a grasp's damping and with K above Colgate & Schenkel's 2 b / T (b = 0.0069,
    2b/T = 13.9 N*m/rad) the wall puts energy in (E grows positive) and the stylus keeps bouncing off it."""
    passive = _run(OmniWallEnv(grasp=(0.0, 0.0, 50.0), stiffness=5.0, damping=0.0,
                               quantize=False, friction="lugre"))
    E = np.array([e for _, _, e, _ in passive])
    pen = np.array([p for *_, p in passive])
    assert E.max() <= 0.5 * 5.0 * pen.max() ** 2 and E[-1] < 0
    assert np.ptp(pen[-200:]) < 0.5 * np.ptp(pen[200:400])  # the oscillation decays
    env = OmniWallEnv(grasp=(0.0, 0.0, 50.0), stiffness=30.0, damping=0.0, quantize=False,
                      duration_s=1.0)
    env.device.scale_friction(0.0)
    active = _run(env)
    assert active[-1][2] > 1e-4
    assert min(p for *_, p in active[-500:]) < 0  # it keeps bouncing off the wall
    assert min(pen[-500:]) > 0  # the passive one stays in contact


def test_sync_vector_env_rows_are_single_envs_seeded_seed_plus_i():
    venv = gym.make_vec("omni_sim/OmniWall-v0", num_envs=2, vectorization_mode="sync",
                        duration_s=0.05, stiffness=8.0)
    obs, _ = venv.reset(seed=3)
    rows = []
    for _ in range(40):
        u = [e.unwrapped.wall_command() for e in venv.envs]
        obs, r, te, tr, info = venv.step(np.stack(u))
        rows.append(obs.copy())
    single = _run(gym.make("omni_sim/OmniWall-v0", duration_s=0.05, stiffness=8.0), 40, seed=4)
    assert np.array_equal(np.array([s[0] for s in single]), np.array(rows)[:, 1])


@pytest.mark.parametrize("kw", [{"grasp": "iron"}, {"delay": -1}, {"stiffness": float("nan")},
                                {"gamma1_set_deg": 500.0}])
def test_bad_options_raise_value_error(kw):
    with pytest.raises(ValueError):
        OmniWallEnv(**kw)
