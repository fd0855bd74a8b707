"""What experiment tells two candidates apart that explain the data alike (the report's
``separating_experiment`` of a tie)."""

#: What experiment separates two candidates that explain the data alike (unordered pairs).
SEPARATING_EXPERIMENTS = {
    frozenset({"joint_stiffness", "gravity_tilt"}):
        "hold the yaw at several angles up to +-0.9 rad at two arm poses of very different reach "
        "(e.g. gamma1=25/gamma2=115 deg vs gamma1=65/gamma2=70 deg): a spring's torque is linear in "
        "theta and the same at every pose, gravity's goes with sin(theta) and scales with the arm's "
        "mass moment",
    frozenset({"gravity_tilt", "position_offset"}):
        "steps around several yaw set points at two arm poses: a bias is the same everywhere, a "
        "tilt's torque changes with yaw angle and reach",
    frozenset({"joint_stiffness", "position_offset"}):
        "steps around several yaw set points: a spring's torque grows with the angle, a bias does not",
    frozenset({"time_delay", "actuator_lag"}):
        "sines above the resonance (8-20 Hz) or the command-to-angle response: a lag rolls the "
        "gain off, a delay only adds phase -w*tau",
    frozenset({"coulomb_friction", "viscous_damping"}):
        "sines at the same frequency and 2-3 amplitudes: Coulomb damping falls with amplitude, "
        "viscous does not",
    frozenset({"armature", "torque_gain"}):
        "repeat a step or sine sweep at a second kp: inertia and gain shift the resonance "
        "differently with kp",
    frozenset({"viscous_damping", "time_delay"}):
        "sines near and above the resonance: damping lowers the peak, delay raises it",
    frozenset({"viscous_damping", "actuator_lag"}):
        "sines near and above the resonance: damping lowers the peak, a lag raises it",
    frozenset({"torque_saturation", "coulomb_friction"}):
        "steps of 2-3 sizes: saturation only bites on large steps, friction on small ones",
    frozenset({"presliding_friction", "coulomb_friction"}):
        "small steps and slow sines of 1-5 mrad (kp*gear*|e| below the static level): pre-sliding "
        "follows them elastically (the loop gets stiffer, the small-amplitude resonance moves up) "
        "and creeps on to the set point; a hard Coulomb stick does not move at all until "
        "kp*gear*|e| exceeds Fc and then stops a constant Fc/(kp*gear) short",
    frozenset({"stribeck_friction", "coulomb_friction"}):
        "slow triangle references (constant speeds 0.02-1 rad/s) and slow ramps from rest: the torque "
        "kp*gear*e needed to keep moving falls with speed from Fs to Fc with Stribeck friction, "
        "it is flat with Coulomb; from rest Stribeck breaks away at Fs and jumps (stick-slip)",
    frozenset({"presliding_friction", "stribeck_friction"}):
        "steps of a few mrad: pre-sliding moves elastically by tau/sigma0 below the break-away, "
        "a Stribeck stick does not move by even one encoder count",
    frozenset({"drive_compliance", "armature"}):
        "small sines or a chirp from 10 to 100 Hz: a compliant cable adds a resonance/antiresonance "
        "pair near sqrt(k (1/J_rotor + 1/J_out)) that moves with the arm pose (J_out), a rotor "
        "inertia only lowers the ~3.4 Hz loop resonance; or measure the turret (tip position) "
        "against the encoder: they differ by tau/k only with a compliant cable",
    frozenset({"drive_compliance", "actuator_lag"}):
        "sines above the resonance (10-60 Hz): a lag rolls the gain off monotonically, a compliant "
        "drive adds a resonance peak near sqrt(k (1/J_rotor + 1/J_out)) and changes with the pose",
    frozenset({"drive_compliance", "backlash"}):
        "sines of 2-3 amplitudes at one frequency: backlash is a fixed dead angle at every reversal "
        "(its effect shrinks as the amplitude grows), compliance deflects in proportion to the "
        "transmitted torque (the same fraction at every amplitude)",
    frozenset({"backlash", "coulomb_friction"}):
        "slow sines around reversals at 2-3 amplitudes, with the turret or tip measured (camera, "
        "tip tracker) against the encoder: with backlash the motor angle runs through +-b while "
        "the turret rests at each reversal, with Coulomb friction the motor itself stops",
    frozenset({"arm_mass", "armature"}):
        "repeat the runs at two arm poses of very different reach (gamma1=25/gamma2=115 deg vs "
        "gamma1=65/gamma2=90 deg): a link mass changes the yaw inertia by m*r^2 with the link's "
        "distance r from the yaw axis (and the arm's sag), an armature by the same amount at every pose",
    frozenset({"arm_mass", "torque_gain"}):
        "repeat the runs at two arm poses of very different reach: a link mass shifts the resonance "
        "differently at each pose, a torque constant by the same factor at every pose",
    frozenset({"cogging", "gravity_tilt"}):
        "hold the yaw at closely spaced angles (every 1-2 deg over the range) or follow a slow ramp: "
        "cogging's torque repeats every 2*pi/n (n periods per turn, 8 deg for the Omni estimate), "
        "a tilt's torque goes with sin(theta) over the whole range and scales with the arm's reach",
    frozenset({"cogging", "joint_stiffness"}):
        "hold the yaw at closely spaced angles (every 1-2 deg) or follow a slow ramp: cogging's "
        "torque repeats every 2*pi/n, a spring's grows linearly with theta",
    frozenset({"cogging", "position_offset"}):
        "steps around set points a fraction of a cogging period (2*pi/n) apart: the offset cogging "
        "leaves changes sign along theta, a bias does not",
}
DEFAULT_SEPARATION = ("repeat the worst-fitting runs at other amplitudes, frequencies and poses")


def separating_experiment(a: str, b: str) -> str:
    """The experiment that would separate candidate ``a`` from ``b``."""
    return SEPARATING_EXPERIMENTS.get(frozenset({a, b}), DEFAULT_SEPARATION)
