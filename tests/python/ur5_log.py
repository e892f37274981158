"""An independent simulator of the UR5 in MuJoCo that writes a robot-style log (CSV), for the
acceptance test of graybox's log import.

The arm is the URDF's rigid-body dynamics and nothing else (no contacts, limits, damping,
armature or friction). A PD controller with gravity compensation tracks a smooth random
reference; its torque is computed at each log sample and held until the next one (zero-order
hold, as the learned model assumes). Sample times jitter around a nominal rate, and the logger
then drops a few rows and pauses for a block in the middle, as a real logger does.

Joint order: the URDF's actuated (non-fixed) joints in MuJoCo's order, which `load` checks is
the order they appear in the URDF file (for ur5.urdf: shoulder_pan_joint, shoulder_lift_joint,
elbow_joint, wrist_1_joint, wrist_2_joint, wrist_3_joint). Every array's joint axis, and the
CSV's columns, use that order.

Only numpy and mujoco; seeded by numpy Generators, so a seed gives the same log.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

# Tags MuJoCo must not see: visual/collision reference meshes that are not in the fixtures,
# and gazebo/transmission are ROS-only elements.
_STRIPPED_TAGS = ("visual", "collision", "gazebo", "transmission")

# Integration substeps are at most this long: RK4 at 1e-4 s is far below the arm's time
# scales, so the simulation is the exact ODE solution to well below a log's precision.
MAX_SUBSTEP = 1e-4

GRAVITY = (0.0, 0.0, -9.81)

# A pose away from singularities (elbow bent, wrist not aligned) around which the reference
# moves by at most ~1 rad per joint.
NOMINAL_Q = np.array([0.0, -1.2, 1.5, -1.0, -1.5, 0.0])

# Closed-loop natural frequency and damping of each joint's PD (per unit of that joint's
# inertia): 5 Hz is faster than the reference (<= 1.5 Hz) so it tracks, and slow enough that
# a torque held for a 1-2 ms sample stays well inside the stable range (omega * dt ~ 0.03).
PD_OMEGA = 2 * math.pi * 5.0
PD_ZETA = 0.8


@dataclass
class Trajectory:
    """Samples of the simulated arm: t (n,), q, qdot, u (n, 6); u[k] is the torque held on
    [t[k], t[k+1])."""

    t: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    u: np.ndarray

    def take(self, keep: np.ndarray) -> Trajectory:
        return Trajectory(self.t[keep], self.q[keep], self.qdot[keep], self.u[keep])


@dataclass
class Reference:
    """q_ref(t) = nominal + sum_k a_k sin(2 pi f_k t + phi_k), per joint (arrays (6, K))."""

    nominal: np.ndarray
    amp: np.ndarray
    freq: np.ndarray
    phase: np.ndarray

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Reference position and velocity at time t."""
        w = 2 * math.pi * self.freq
        arg = w * t + self.phase
        return (self.nominal + (self.amp * np.sin(arg)).sum(axis=1),
                (self.amp * w * np.cos(arg)).sum(axis=1))


# ----------------------------------------------------------------------------------------
# Model


def _strip_urdf(urdf_path: str | Path) -> str:
    """The URDF text without mesh-bearing or ROS-only elements, with MuJoCo compiler options
    that keep every link a body (no fusing, no inertia rebalancing) so the dynamics are the
    URDF's as written."""
    root = ET.parse(urdf_path).getroot()
    for parent in list(root.iter()):
        for child in list(parent):
            if child.tag in _STRIPPED_TAGS:
                parent.remove(child)
    if root.find("mujoco") is None:
        mj = ET.SubElement(root, "mujoco")
        ET.SubElement(mj, "compiler", discardvisual="true", fusestatic="false",
                      balanceinertia="false", strippath="true")
    return ET.tostring(root, encoding="unicode")


def urdf_joint_names(urdf_path: str | Path) -> list[str]:
    """The URDF's actuated joints (not fixed, not mimic) in file order."""
    root = ET.parse(urdf_path).getroot()
    return [j.get("name", "") for j in root.findall("joint")
            if j.get("type") != "fixed" and j.find("mimic") is None]


def joint_names(model: mujoco.MjModel) -> list[str]:
    """MuJoCo's joints in its order (= the order of qpos/qvel here; see `load`)."""
    return [model.joint(j).name for j in range(model.njnt)]


def load(urdf_path: str | Path) -> mujoco.MjModel:
    """The UR5 as MuJoCo model whose dynamics are exactly the URDF's rigid-body dynamics."""
    model = mujoco.MjModel.from_xml_string(_strip_urdf(urdf_path))
    # Nothing but M(q) qdd + c(q, qd) + g(q) = u: no contacts, limits or other constraints...
    model.opt.disableflags |= (mujoco.mjtDisableBit.mjDSBL_CONTACT
                               | mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    model.jnt_limited[:] = 0
    model.jnt_actfrclimited[:] = 0
    # ...and no joint-space terms MuJoCo would add to them (the URDF's damping and friction
    # are 0 anyway; armature is MuJoCo-only).
    model.dof_damping[:] = 0.0
    model.dof_armature[:] = 0.0
    model.dof_frictionloss[:] = 0.0
    model.jnt_stiffness[:] = 0.0
    model.opt.gravity[:] = GRAVITY
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    model.opt.timestep = MAX_SUBSTEP
    _check_order(model, urdf_path)
    return model


def _check_order(model: mujoco.MjModel, urdf_path: str | Path) -> None:
    """Fail unless MuJoCo's joints are the URDF's actuated joints in file order, each a
    hinge with one qpos and one qvel at its own index, so arrays and columns line up."""
    names = joint_names(model)
    if names != urdf_joint_names(urdf_path):
        raise ValueError(f"MuJoCo joint order {names} is not the URDF's "
                         f"{urdf_joint_names(urdf_path)}")
    idx = np.arange(model.njnt)
    hinge = mujoco.mjtJoint.mjJNT_HINGE
    if (model.nq != model.njnt or model.nv != model.njnt or np.any(model.jnt_type != hinge)
            or np.any(model.jnt_qposadr != idx) or np.any(model.jnt_dofadr != idx)):
        raise ValueError("expected one hinge per joint with qpos/qvel at the joint's index")


# ----------------------------------------------------------------------------------------
# Controller


def random_reference(rng: np.random.Generator, n_joints: int = 6,
                     n_sines: int = 3) -> Reference:
    """A smooth random reference: per joint, n_sines sines at 0.2-1.5 Hz whose amplitudes sum
    to 0.4-1.0 rad, so the joint stays within ~1 rad of NOMINAL_Q."""
    freq = rng.uniform(0.2, 1.5, (n_joints, n_sines))
    weights = rng.uniform(0.2, 1.0, (n_joints, n_sines))
    total = rng.uniform(0.4, 1.0, (n_joints, 1))
    amp = weights / weights.sum(axis=1, keepdims=True) * total
    phase = rng.uniform(0, 2 * math.pi, (n_joints, n_sines))
    return Reference(NOMINAL_Q[:n_joints].copy(), amp, freq, phase)


def pd_gains(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """Per-joint Kp, Kd from the diagonal of M at the nominal pose, so every joint gets the
    same closed-loop bandwidth whatever its inertia."""
    data = mujoco.MjData(model)
    data.qpos[:] = NOMINAL_Q
    mujoco.mj_forward(model, data)
    m = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, m)
    inertia = np.diag(m)
    return inertia * PD_OMEGA ** 2, inertia * 2 * PD_ZETA * PD_OMEGA


class Controller:
    """u = Kp (q_ref - q) + Kd (qd_ref - qd) + g(q), with g(q) MuJoCo's qfrc_bias at zero
    velocity (qfrc_bias at the actual velocity would also cancel Coriolis terms; a plain
    gravity-compensated PD is what robot controllers commonly run)."""

    def __init__(self, model: mujoco.MjModel, ref: Reference) -> None:
        self.model, self.ref = model, ref
        self.kp, self.kd = pd_gains(model)
        self._scratch = mujoco.MjData(model)  # its qvel stays 0

    def gravity(self, q: np.ndarray) -> np.ndarray:
        self._scratch.qpos[:] = q
        mujoco.mj_forward(self.model, self._scratch)
        return self._scratch.qfrc_bias.copy()

    def __call__(self, t: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        q_ref, qd_ref = self.ref.at(t)
        return self.kp * (q_ref - q) + self.kd * (qd_ref - qd) + self.gravity(q)


# ----------------------------------------------------------------------------------------
# Simulation


def sample_times(rng: np.random.Generator, duration: float, rate: float,
                 jitter: float) -> np.ndarray:
    """Times from 0 to about `duration`, each step 1/rate times (1 + U(-jitter, jitter))."""
    n = int(round(duration * rate))
    steps = (1.0 + rng.uniform(-jitter, jitter, n)) / rate
    return np.concatenate([[0.0], np.cumsum(steps)])


def _advance(model: mujoco.MjModel, data: mujoco.MjData, u: np.ndarray, t_next: float) -> None:
    """Integrate from data.time to exactly t_next with u held: equal RK4 substeps no longer
    than MAX_SUBSTEP, so the last one lands on the sample time."""
    span = t_next - data.time
    n = max(1, math.ceil(span / MAX_SUBSTEP - 1e-9))
    model.opt.timestep = span / n
    data.qfrc_applied[:] = u
    for _ in range(n):
        mujoco.mj_step(model, data)
    data.time = t_next  # drop the rounding of n additions


def simulate(model: mujoco.MjModel, times: np.ndarray, ref: Reference,
             delay: float = 0.0) -> Trajectory:
    """The arm under the controller, sampled at `times`; it starts on the reference (q and
    qdot), so there is no start-up transient. With `delay`, each sample's torque acts from
    its time plus the delay until the next one's does (a drive that applies its command
    late; the first acts from the start): u[k] is what the controller logged at t[k]."""
    ctrl = Controller(model, ref)
    data = mujoco.MjData(model)
    data.time = float(times[0])
    data.qpos[:], data.qvel[:] = ref.at(float(times[0]))
    n, nv = len(times), model.nv
    q, qd, u = np.zeros((n, nv)), np.zeros((n, nv)), np.zeros((n, nv))
    acting = 0  # the sample whose torque acts now
    for k, t in enumerate(times):
        q[k], qd[k] = data.qpos, data.qvel
        u[k] = ctrl(float(t), q[k], qd[k])
        if k + 1 == n:
            break
        end = float(times[k + 1])
        # Samples up to k whose torque starts acting before the step's end take over in turn.
        for j in range(acting + 1, k + 1):
            switch = float(times[j] + delay)
            if switch < end:
                if switch > data.time:
                    _advance(model, data, u[acting], switch)
                acting = j
        _advance(model, data, u[acting], end)
    return Trajectory(np.asarray(times, dtype=float).copy(), q, qd, u)


def with_noise(log: Trajectory, rng: np.random.Generator, q_sigma: float,
               u_relative: float) -> Trajectory:
    """What the sensors report of `log`: positions with N(0, q_sigma²) added, efforts with
    N(0, (u_relative · each joint's RMS effort)²); the true velocities stay (a check only)."""
    q = log.q + rng.normal(0.0, q_sigma, log.q.shape)
    scale = u_relative * np.sqrt(np.mean(log.u ** 2, axis=0))
    u = log.u + rng.normal(0.0, 1.0, log.u.shape) * scale
    return Trajectory(log.t, q, log.qdot, u)


# ----------------------------------------------------------------------------------------
# Logs


def as_log(traj: Trajectory, rng: np.random.Generator, drop: float = 0.02,
           pause: float = 0.3) -> Trajectory:
    """What a logger keeps of `traj`: ~`drop` of the rows lost at random, and nothing for
    `pause` seconds around the middle (the arm kept moving). A row's u stays the torque held
    from its own sample, so across a gap u is not constant between consecutive rows."""
    t = traj.t
    mid = 0.5 * (t[0] + t[-1])
    keep = ~((t > mid - pause / 2) & (t < mid + pause / 2))
    lost = rng.random(len(t)) < drop
    lost[0] = lost[-1] = False  # keep the log's span
    return traj.take(keep & ~lost)


def generate_log(model: mujoco.MjModel, seed: int, duration: float = 4.0,
                 rate: float = 1000.0, jitter: float = 0.05, drop: float = 0.02,
                 pause: float = 0.3, delay: float = 0.0) -> Trajectory:
    """A jittered, gappy log of `duration` seconds at about `rate` Hz from `seed`, its
    torques acting `delay` after they were logged."""
    rng = np.random.default_rng(seed)
    ref = random_reference(rng, model.nv)
    times = sample_times(rng, duration, rate, jitter)
    return as_log(simulate(model, times, ref, delay), rng, drop, pause)


def held_out(model: mujoco.MjModel, seed: int, duration: float = 1.0,
             rate: float = 500.0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A clean trajectory (uniform `rate`, no jitter, no drops) from another seed, as
    (t, q, qdot, u); u[k] is held on [t[k], t[k+1])."""
    rng = np.random.default_rng(seed)
    ref = random_reference(rng, model.nv)
    times = np.arange(int(round(duration * rate)) + 1) / rate
    traj = simulate(model, times, ref)
    return traj.t, traj.q, traj.qdot, traj.u


def write_csv(path: str | Path, log: Trajectory, joint_names: list[str]) -> None:
    """Columns: time, q per joint (named as the joint), tau_<joint>, then qdot_<joint> (the
    true velocities: a check for the test, not something a real log has). Full precision."""
    header = (["time"] + list(joint_names) + [f"tau_{j}" for j in joint_names]
              + [f"qdot_{j}" for j in joint_names])
    table = np.column_stack([log.t, log.q, log.u, log.qdot])
    np.savetxt(path, table, delimiter=",", header=",".join(header), comments="", fmt="%.17g")
