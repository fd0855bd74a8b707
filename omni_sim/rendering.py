"""Rendering of the environments, written once: the render modes that can work in this
process, and :class:`Viewport`, the picture of an environment's ``MjData`` (offscreen or in
MuJoCo's passive viewer)."""

from __future__ import annotations

import os
import sys

import gymnasium as gym
import mujoco

from .options import InvalidOptionError

__all__ = ["RENDER_MODES", "Viewport", "available_render_modes", "render_mode_problem"]

#: The render modes the environments implement (their class ``metadata``).  An instance's
#: ``metadata["render_modes"]`` lists those that can work in this process
#: (:func:`available_render_modes`), so that gymnasium's ``check_env``, which tries every
#: advertised mode, does not open a window without a display.
RENDER_MODES = ("human", "rgb_array")
#: MuJoCo's OpenGL backends that need no display: ``MUJOCO_GL=egl`` or ``osmesa`` (Linux), CGL
#: (macOS); the default, GLFW, opens an invisible window and so needs one.
_DISPLAYLESS_GL = ("mujoco.egl", "mujoco.osmesa", "mujoco.cgl")
_HEADLESS_HINT = ("headless, use render_mode='rgb_array' with MUJOCO_GL=egl (or osmesa) set "
                  "before mujoco is imported")


def _has_display() -> bool:
    """Whether a window can open: macOS and Windows have a desktop; elsewhere (X11, Wayland) a
    display must be named by ``DISPLAY`` or ``WAYLAND_DISPLAY``."""
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def render_mode_problem(mode: str) -> str | None:
    """Why ``mode`` cannot render in this process, or None when it can.

    ``"human"`` (MuJoCo's passive viewer, a GLFW window) needs a display; without one GLFW's
    failure ends the whole process, so it is refused here first.  ``"rgb_array"`` needs an
    OpenGL context from the backend MuJoCo chose when it was imported (``MUJOCO_GL``): EGL,
    OSMesa and CGL need no display, GLFW does.
    """
    if mode == "human":
        if _has_display():
            return None
        return ("render_mode='human' opens a window and needs a display (neither DISPLAY nor "
                f"WAYLAND_DISPLAY is set); {_HEADLESS_HINT}")
    backend = getattr(getattr(mujoco, "GLContext", None), "__module__", None)
    if backend in _DISPLAYLESS_GL or (backend == "mujoco.glfw" and _has_display()):
        return None
    why = ("MuJoCo's default backend, GLFW, needs a display and none is set" if backend == "mujoco.glfw"
           else f"MuJoCo has no usable OpenGL backend (MUJOCO_GL={os.environ.get('MUJOCO_GL')!r})")
    return f"render_mode='rgb_array' needs an OpenGL context: {why}; {_HEADLESS_HINT}"


def available_render_modes() -> list[str]:
    """The render modes that can work in this process (see :func:`render_mode_problem`)."""
    return [m for m in RENDER_MODES if render_mode_problem(m) is None]


class Viewport:
    """The picture of a model's data for an environment: offscreen with :class:`mujoco.Renderer`
    (``"rgb_array"``) or in MuJoCo's passive viewer (``"human"``).  The mode is checked when
    the environment is made: unknown, or unable to work here, raises :class:`InvalidOptionError`."""

    def __init__(self, model: mujoco.MjModel, render_mode: str | None, width: int, height: int,
                 camera: str | None):
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise InvalidOptionError(f"render_mode must be one of {list(RENDER_MODES)} or None, "
                                     f"got {render_mode!r}")
        problem = render_mode_problem(render_mode) if render_mode is not None else None
        if problem is not None:
            raise InvalidOptionError(problem)
        self.mode, self.model = render_mode, model
        self.size = (int(height), int(width))
        if min(self.size) < 1:
            raise InvalidOptionError(f"render size must be positive, got {width}x{height}")
        if camera is not None and mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera) < 0:
            if camera != "side":  # the default falls back to the free camera
                raise InvalidOptionError(f"the model has no camera named {camera!r}")
            camera = None
        self.camera = camera
        self._renderer = None
        self._viewer = None

    def render(self, data: mujoco.MjData):
        """An RGB image ``(height, width, 3)`` uint8 (``"rgb_array"``), or update the viewer."""
        if self.mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' "
                            "or 'human' when making the environment")
            return None
        if self.mode == "human":
            if self._viewer is None:
                from mujoco import viewer  # needs a display (checked when made)
                self._viewer = viewer.launch_passive(self.model, data)
            self._viewer.sync()
            return None
        if self._renderer is None:
            h, w = self.size
            vis = self.model.vis.global_
            vis.offheight, vis.offwidth = max(vis.offheight, h), max(vis.offwidth, w)
            self._renderer = mujoco.Renderer(self.model, h, w)
        self._renderer.update_scene(data, camera=self.camera if self.camera else -1)
        return self._renderer.render().copy()

    def close(self) -> None:
        """Release the renderer and the viewer (safe to call twice)."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
