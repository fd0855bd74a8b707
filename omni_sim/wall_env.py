"""``omni_sim/OmniWall-v0``: a virtual wall rendered on the virtual Omni's yaw, pushed by a hand.

The stylus's yaw is held by a hand model and pushed into a virtual wall at ``wall_rad``
(penetration ``theta - wall_rad > 0``).  Every servo period the agent outputs the motor command
[V]; :meth:`OmniWallEnv.wall_command` gives the standard renderer's command (a spring ``K`` and
a damper ``B`` on the backward-difference velocity of the encoder reading, through the motor's
torque constant, :func:`wall_torque`), so ``env.step(env.unwrapped.wall_command())`` renders it.
Same :class:`~omni_sim.device.Device` and :class:`~omni_sim.device.Engine` as ``OmniYaw-v0``,
the same friction families, encoder quantisation (15000 counts/rev) and an optional loop delay
(whole servo periods, between the command and the drive).

**Hand model** -- the grasp is a mass-spring-damper at the stylus tip, put into the physics
(the yaw dof's ``armature`` += I_h, ``damping`` += c_h, a joint spring k_h whose rest angle is
``wall_rad + push_rad``: the hand pushes towards a point ``push_rad`` behind the wall).
Translational values at the tip, converted with the tip radius ``TIP_RADIUS_M`` (I = m r^2,
c r^2, k r^2); all are ESTIMATES of the order the literature reports, not measurements:

* ``loose``: 0.05 kg, 1.5 N s/m, 50 N/m -- a light fingertip hold; the lower end of Hajian &
  Howe (1997, fingertip: a few grams, 1.5-3.5 N s/m, 50-400 N/m as grip force rises);
* ``medium``: 0.2 kg, 3 N s/m, 200 N/m -- a pen grasp of a stylus, of the order Fu & Cavusoglu
  (2012, stylus on a Phantom Premium, 1-3 N grip) identify;
* ``firm``: 0.55 kg, 6.5 N s/m, 400 N/m -- arm and hand: mass and damping of one identified
  trial on a HapticMaster (Nature Sci. Rep. 5:18004, 2015: 0.554 kg, 6.45 N s/m, 135 N/m), the
  stiffness raised to a firm grip's (our estimate).

**Passivity observer** (Hannaford & Ryu 2002) -- ``info["energy"]`` is
``E_k = sum_{j<k} tau_j (y_{j+1} - y_j)`` [J]: the energy the motor's torque ``tau_j`` (applied
command x torque constant) put into the device over each servo period, computed from the encoder
readings ``y`` as a real observer must.  Sign: positive = energy flowed into the device from the
rendering port (the wall gave energy: active); a passive wall keeps ``E_k <= 0`` up to the
energy its spring stores (``info["wall_energy"] = -E_k``, the energy the wall absorbed, is the
observer in Hannaford & Ryu's sign, negative when active).  ``info["penetration"]`` is the true
penetration [rad] (``theta - wall_rad``, negative outside).

**Observation** ``Box(float64, (3,))``: measured yaw [rad], its backward difference
``(y_k - y_{k-1}) / T`` [rad/s], measured penetration [rad].  **Action** ``Box(-V, V, (1,))``:
the motor command [V] (clipped by the drive).  **Reward**: ``-penetration_true**2`` [rad^2].
**Episode**: ``duration_s`` (truncated), terminated if the state leaves its bounds.

Vector environments: ``gym.make_vec("omni_sim/OmniWall-v0", num_envs=N,
vectorization_mode="sync")`` (gymnasium's ``SyncVectorEnv``: sub-environment i is this
environment seeded ``seed + i``); no native batch version.
"""

from __future__ import annotations

import copy

from identification.errors import UserError

from . import model as om
from .device import CONTROL_PERIOD_S, Device
from .env import OmniEnv
from .options import InvalidOptionError
from .wall_task import (GRASPS, TIP_RADIUS_M, WallTask, add_hand, check_wall_settings,
                        grasp_impedance, wall_torque)

__all__ = ["OmniWallEnv", "wall_torque", "GRASPS", "TIP_RADIUS_M"]


class OmniWallEnv(OmniEnv):
    """A virtual wall on the virtual Omni's yaw, pushed by a hand model (see the module doc):
    :class:`omni_sim.env.OmniEnv` asking a :class:`omni_sim.wall_task.WallTask`.

    Parameters (all make-time): ``model_path``/``friction`` (as ``OmniYaw-v0``), ``stiffness``
    K [N*m/rad] (default 5) and ``damping`` B [N*m*s/rad] (default 0.002) of the built-in
    renderer, ``wall_rad`` (0), ``push_rad`` (0.02), ``grasp`` ("loose", "medium", "firm" or a
    (mass, damping, stiffness) tuple at the tip), ``quantize`` (True), ``delay`` (0 servo
    periods), ``duration_s`` (1.0), ``start_rad`` (start angle at rest, default wall - 0.005),
    ``gamma1_set_deg``/``gamma2_set_deg`` (65, 90), ``control_period_s`` (1 ms), and the
    rendering's ``render_mode`` (None, ``"rgb_array"`` or ``"human"``), ``render_width``,
    ``render_height`` (640 x 480) and ``camera`` (``"side"``) as ``OmniYaw-v0``'s: a mode that
    cannot work in this process raises :class:`InvalidOptionError` when made and is not in the
    instance's ``metadata["render_modes"]`` (:func:`omni_sim.env.render_mode_problem`).

    The settings are read back as the task's: ``K``, ``B``, ``wall_rad``, ``push_rad``,
    ``quantize``, ``delay``, ``n`` (periods per episode), ``start_rad``, ``gamma_set``, ``hand``
    (the grasp at the yaw), ``T`` [s], ``kt`` [N*m/V], ``vlim`` [V].
    """

    def __init__(self, model_path=None, friction=None, stiffness=5.0, damping=0.002,
                 wall_rad=0.0, push_rad=0.02, grasp="medium", quantize=True, delay=0,
                 duration_s=1.0, start_rad=None, gamma1_set_deg=65.0, gamma2_set_deg=90.0,
                 control_period_s=CONTROL_PERIOD_S, render_mode=None, render_width=640,
                 render_height=480, camera="side"):
        try:
            model = copy.deepcopy(om.load_model(model_path, friction))
            dev = Device(model, float(control_period_s))
            dev.check_pose(float(gamma1_set_deg), float(gamma2_set_deg))
        except UserError as exc:
            raise InvalidOptionError(str(exc)) from None
        check_wall_settings(stiffness, damping, wall_rad, push_rad, duration_s, delay)
        hand = grasp_impedance(grasp)
        add_hand(model, dev, hand, float(wall_rad) + float(push_rad))
        device = Device(model, float(control_period_s))
        task = WallTask(device, hand, stiffness, damping, wall_rad, push_rad, quantize, delay,
                        duration_s, start_rad, (float(gamma1_set_deg), float(gamma2_set_deg)))
        super().__init__(device, task, render_mode, render_width, render_height, camera)

    def wall_command(self):
        """The built-in renderer's command [V] for the current reading (shape (1,))."""
        return self.task.wall_command()

    K = property(lambda self: self.task.K)
    B = property(lambda self: self.task.B)
    wall_rad = property(lambda self: self.task.wall_rad)
    push_rad = property(lambda self: self.task.push_rad)
    quantize = property(lambda self: self.task.quantize)
    delay = property(lambda self: self.task.delay)
    n = property(lambda self: self.task.n)
    start_rad = property(lambda self: self.task.start_rad)
    gamma_set = property(lambda self: self.task.gamma_set)
    hand = property(lambda self: self.task.hand)
    T = property(lambda self: self.task.T)
    kt = property(lambda self: self.task.kt)
    vlim = property(lambda self: self.task.vlim)
