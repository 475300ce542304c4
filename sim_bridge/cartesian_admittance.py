"""Position-based Cartesian admittance IFC of the ACCREA dual arm (2.22/2.23, Fig. 2.7).

Per chain with admittance parameters (M_x, D_x, K_x, all diagonal), at physics rate:

    M_x Δẍ + D_x Δẋ + K_x Δx = h,     Δx = x_c − x_d,     x_d = FK(q_v)

``h`` is the wrist F/T sensor reading with the tool weight removed (what the environment
exerts on the tool, base frame, moment about the chain frame). ``K_x = 0`` gives force
following (2.23). Poses are compared as ``[p_c − p; log(R_c Rᵀ)]`` and ``x_c`` is formed
as ``p_c = p_d + Δp``, ``R_c = exp(Δθ) R_d``.

The compliant pose x_c is tracked by an inner joint position loop: differential IK on
the joint reference (one damped Gauss-Newton step per physics step, all admittance
chains stacked, the null space pulled towards q_v)

    q_ref += g J⁺(q_ref) (x_c ⊖ FK(q_ref)) + (I − J⁺J) k_null Δt (q_v − q_ref)

and stiff joint PD servos (MuJoCo actuators, gains ``joint_gains``) tracking q_ref with
gravity and dynamics compensation and integral action (``joint_ki``). The IK is kinematic (it does not use the measured q):
feeding the measured pose back through an integrator makes the loop unstable against a
stiff environment (Routh: M k_ik K_servo > D K), the classic admittance pitfall.

Stability with a rigid grasp (weld to a drawer, door, crank) needs enough virtual mass or
damping: with the 1-step F/T delay of a 1 kHz loop, M_x = 2 kg (ζ = 1) oscillates while
M_x = 10 kg (D_x = 2 sqrt(K_x M_x)) is stable in every mechanism scene; stiffer servos
make it worse, not better.
"""

from dataclasses import dataclass, field

import mujoco
import numpy as np

__all__ = ['CartesianAdmittanceLaw', 'exp3', 'log3']


def exp3(w):
    """Rotation matrix of rotation vector ``w`` [rad] (Rodrigues)."""
    theta = float(np.linalg.norm(w))
    k = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    if theta < 1e-9:
        return np.eye(3) + k
    a = np.sin(theta) / theta
    b = (1.0 - np.cos(theta)) / theta ** 2
    return np.eye(3) + a * k + b * (k @ k)


def log3(r):
    """Rotation vector [rad] of rotation matrix ``r`` (inverse of :func:`exp3`)."""
    cos = np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0)
    theta = np.arccos(cos)
    v = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    if theta < 1e-6:
        return 0.5 * v
    if np.pi - theta < 1e-6:
        # Near pi: axis from the symmetric part.
        axis = np.sqrt(np.maximum((np.diag(r) + 1.0) / 2.0, 0.0))
        i = int(np.argmax(axis))
        axis = (r[:, i] + r[i, :]) / 2.0
        axis[i] = axis[i] if axis[i] != 0 else 1.0
        return theta * axis / np.linalg.norm(axis)
    return theta / (2.0 * np.sin(theta)) * v


@dataclass
class _Chain:
    name: str
    site_id: int
    mass: np.ndarray
    damping: np.ndarray
    stiffness: np.ndarray
    p_d: np.ndarray = field(default_factory=lambda: np.zeros(3))
    r_d: np.ndarray = field(default_factory=lambda: np.eye(3))
    dx: np.ndarray = field(default_factory=lambda: np.zeros(6))
    dxd: np.ndarray = field(default_factory=lambda: np.zeros(6))


class CartesianAdmittanceLaw:
    """The ACCREA emulation: admittance per chain, IK, stiff joint servos.

    Args:
        admittance: Chain id -> object with ``stiffness``, ``damping``, ``mass`` (6 each).
        joint_gains: (K_p [Nm/rad], K_d [Nms/rad]) of the inner joint position servos.
        joint_ki: Integral gain K_i [Nm/(rad s)] of the servos (exact static tracking).
        ik_gain: Fraction of the Gauss-Newton IK step taken per physics step (0, 1].
        k_null: Null-space gain towards q_v in [1/s].
        ik_damping: Damping λ of the least-squares pseudo-inverse.
    """

    name = 'accrea'

    def __init__(self, admittance, joint_gains=(3000.0, 30.0), joint_ki=30000.0, ik_gain=1.0,
                 k_null=5.0, ik_damping=1e-3):
        self.admittance = dict(admittance)
        self.joint_gains = tuple(float(g) for g in joint_gains)
        self.ik_gain = float(ik_gain)
        self.joint_ki = float(joint_ki)
        self.k_null = float(k_null)
        self.ik_damping = float(ik_damping)
        self.chains = []

    def setup(self, sim):
        """Set the servo gains and bind the chains to sites."""
        m = sim.model
        kp, kd = self.joint_gains
        for a in sim.actuator_ids:
            m.actuator_gainprm[a, 0] = kp
            m.actuator_biasprm[a, :3] = (0.0, -kp, -kd)
        self.chains = []
        for chain, adm in self.admittance.items():
            self.chains.append(_Chain(
                name=chain, site_id=sim.site_id(chain),
                mass=np.asarray(adm.mass, float).copy(),
                damping=np.asarray(adm.damping, float).copy(),
                stiffness=np.asarray(adm.stiffness, float).copy()))
        n = len(sim.joint_names)
        self._jacp = np.zeros((3, m.nv))
        self._jacr = np.zeros((3, m.nv))
        self._jac = np.zeros((6 * len(self.chains), n))
        self._err = np.zeros(6 * len(self.chains))
        self._eye_n = np.eye(n)
        self._eye_m = np.eye(6 * len(self.chains))
        self.q_ref = np.zeros(n)
        self.q_v = np.zeros(n)
        self.tau_i = np.zeros(n)

    def reset(self, sim, q0):
        """Start at rest at ``q0``: x_d = FK(q0), Δx = 0."""
        self.q_ref = np.array(q0, dtype=float)
        self.q_v = self.q_ref.copy()
        self.tau_i = np.zeros(len(self.q_ref))
        sim.data.ctrl[sim.actuator_index] = self.q_ref
        self._set_desired(sim, self.q_v)
        for c in self.chains:
            c.dx[:] = 0.0
            c.dxd[:] = 0.0

    def command(self, sim, q_v, qd_v=None, tau_offset=None):
        """Latch q_v and map it to the desired poses x_d = FK(q_v)."""
        self.q_v = np.array(q_v, dtype=float)
        self._set_desired(sim, self.q_v)

    def _set_desired(self, sim, q_v):
        for c, (p, r) in zip(self.chains, sim.forward_kinematics(q_v, [c.site_id for c in
                                                                        self.chains])):
            c.p_d, c.r_d = p, r

    def compliant_pose(self, chain):
        """Return (p_c [m], R_c) of the compliant frame x_c of ``chain``."""
        for c in self.chains:
            if c.name == chain:
                return c.p_d + c.dx[:3], exp3(c.dx[3:]) @ c.r_d
        raise KeyError(chain)

    def control(self, sim):
        """Per physics step (after ``mj_step1``): admittance, IK, servo set point."""
        m, d, dt = sim.model, sim.data, sim.dt
        kin = sim.kinematics_data(self.q_ref, jacobians=True)
        for k, c in enumerate(self.chains):
            h = sim.ft_external(c.name)
            acc = (h - c.damping * c.dxd - c.stiffness * c.dx) / c.mass
            c.dxd += dt * acc
            c.dx += dt * c.dxd
            p = kin.site_xpos[c.site_id]
            r = kin.site_xmat[c.site_id].reshape(3, 3)
            r_c = exp3(c.dx[3:]) @ c.r_d
            self._err[6 * k:6 * k + 3] = c.p_d + c.dx[:3] - p
            self._err[6 * k + 3:6 * k + 6] = log3(r_c @ r.T)
            mujoco.mj_jacSite(m, kin, self._jacp, self._jacr, c.site_id)
            self._jac[6 * k:6 * k + 3] = self._jacp[:, sim.dof_index]
            self._jac[6 * k + 3:6 * k + 6] = self._jacr[:, sim.dof_index]
        jac = self._jac
        jjt = jac @ jac.T + self.ik_damping ** 2 * self._eye_m
        pinv = jac.T @ np.linalg.inv(jjt)
        null = self._eye_n - pinv @ jac
        self.q_ref += self.ik_gain * (pinv @ self._err) + null @ (
            (self.k_null * dt) * (self.q_v - self.q_ref))
        d.ctrl[sim.actuator_index] = self.q_ref
        if self.joint_ki:
            self.tau_i += (self.joint_ki * dt) * (self.q_ref - d.qpos[sim.qpos_index])
        d.qfrc_applied[sim.dof_index] = d.qfrc_bias[sim.dof_index] + self.tau_i
