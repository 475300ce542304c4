"""Position-based Cartesian admittance IFC of the ACCREA dual arm (2.22/2.23, Fig. 2.7).

Per chain with admittance parameters (M_x, D_x, K_x, all diagonal), at physics rate:

    M_x Δẍ + D_x Δẋ + K_x Δx = h_f,     Δx = x_c − x_d,     x_d = FK(q_v)

``h`` is the wrist F/T sensor reading with the tool weight removed (what the environment
exerts on the tool, base frame, moment about the chain frame); ``h_f`` is ``h`` after a
first-order low-pass with cutoff ``ft_cutoff`` (default 100 Hz, about the bandwidth of a
filtered industrial F/T sensor; it costs ~5° of phase at the 10 Hz contact mode below).
``K_x = 0`` gives force following (2.23). Poses are compared as ``[p_c − p; log(R_c Rᵀ)]``
and ``x_c`` is formed as ``p_c = p_d + Δp``, ``R_c = exp(Δθ) R_d``.

The admittance is integrated with backward Euler (implicit in D_x and K_x):

    Δẋ⁺ = (M_x Δẋ + Δt (h_f − K_x Δx)) / (M_x + Δt D_x + Δt² K_x),   Δx⁺ = Δx + Δt Δẋ⁺

which is unconditionally stable for any M_x, D_x, K_x >= 0 (M_x may be 0: a pure damper)
and exact in steady state (Δx = K_x⁻¹ h; Δẋ = h / D_x when K_x = 0).

The compliant pose x_c is tracked by an inner joint position loop: differential IK on
the joint reference (one damped Gauss-Newton step per physics step, all admittance
chains stacked, the null space pulled towards q_v)

    q_ref += g J⁺(q_ref) (x_c ⊖ FK(q_ref)) + (I − J⁺J) k_null Δt (q_v − q_ref)

with J⁺ = Jᵀ(JJᵀ + λ²I)⁻¹, λ² = ``ik_damping``² plus, when the smallest singular value σ
of J falls below ``ik_singular_value``, ``ik_max_damping``² (1 − (σ/ε)²) (bounded steps
at singularities, e.g. a stretched arm at the edge of its reach), and q_ref clamped into
the joint position limits shrunk by ``limit_margin``, as a robot controller does: a
reference beyond a limit drove the servo (with its integral action) into MuJoCo's hard
limit constraint, which produced contact-like force spikes of several hundred N at the
tool when the left ACCREA arm reached A6 = 120° while lifting a drawer out of reach.

q_ref is tracked by stiff joint PD servos (MuJoCo actuators, gains ``joint_gains``,
damping integrated implicitly) with gravity and dynamics compensation and a small, clamped
integral action (``joint_ki``, ``joint_ki_limit``: removes the servo's static deflection
under load, so the admittance static check holds, without windup). The IK is kinematic
(it does not use the measured q): feeding the measured pose back through an integrator
makes the loop unstable against a stiff environment (Routh: M k_ik K_servo > D K), the
classic admittance pitfall.

Stability with a rigid grasp (weld/connect to a drawer, door, crank): the environment then
closes a force loop through the servo's Cartesian stiffness K_c (~2·10⁴ N/m, ~3·10³ Nm/rad
here), a mass-spring-damper M_x, D_x, K_x + K_c whose damping ratio is
``D_x / (2 sqrt(K_c M_x))``. A critically damped admittance (D_x = 2 sqrt(K_x M_x)) has
``sqrt(K_x / K_c) ~ 0.16`` there for every M_x, and with the F/T delay it oscillated
(±40 N at M_x = 2 and 10 kg); so D_x must be sized against K_c, not K_x: D_x >= ~1.4
sqrt(K_c M_x). The registry defaults (``accrea_dual_arm``) do this; the integral gain was
lowered from 30000 to 3000 Nm/(rad s) (at 30000 its phase lag made a slow x_d ramp
oscillate by ±40 N).
"""

from dataclasses import dataclass, field

import mujoco
import numpy as np

from ifc_spg.errors import ParameterError

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
    denom: np.ndarray = field(default_factory=lambda: np.ones(6))
    dx: np.ndarray = field(default_factory=lambda: np.zeros(6))
    dxd: np.ndarray = field(default_factory=lambda: np.zeros(6))
    h_f: np.ndarray | None = None


class CartesianAdmittanceLaw:
    """The ACCREA emulation: admittance per chain, IK, stiff joint servos.

    Args:
        admittance: Chain id -> object with ``stiffness``, ``damping``, ``mass`` (6 each).
        joint_gains: (K_p [Nm/rad], K_d [Nms/rad]) of the inner joint position servos.
        joint_ki: Integral gain K_i [Nm/(rad s)] of the servos (exact static tracking).
        joint_ki_limit: Clamp of the integral torque as a fraction of each joint's torque
            limit (anti-windup).
        ft_cutoff: Cutoff [Hz] of the first-order F/T low-pass; ``None``: unfiltered.
        ik_gain: Fraction of the Gauss-Newton IK step taken per physics step (0, 1].
        k_null: Null-space gain towards q_v in [1/s].
        ik_damping: Damping λ of the least-squares pseudo-inverse.
        ik_singular_value: Smallest singular value ε of the stacked Jacobian below which
            the damping grows.
        ik_max_damping: Damping added at a singularity.
        limit_margin: Distance [rad] q_ref keeps from the joint position limits (at most a
            tenth of each joint's range).
    """

    name = 'accrea'

    def __init__(self, admittance, joint_gains=(3000.0, 30.0), joint_ki=3000.0,
                 joint_ki_limit=0.3, ft_cutoff=100.0, ik_gain=1.0, k_null=5.0,
                 ik_damping=1e-3, ik_singular_value=0.02, ik_max_damping=0.02,
                 limit_margin=0.01):
        self.admittance = dict(admittance)
        self.joint_gains = tuple(float(g) for g in joint_gains)
        self.ik_gain = float(ik_gain)
        self.joint_ki = float(joint_ki)
        self.joint_ki_limit = float(joint_ki_limit)
        if ft_cutoff is not None and not float(ft_cutoff) > 0:
            raise ParameterError(f'ft_cutoff must be > 0 Hz or None (unfiltered), got '
                                 f'{ft_cutoff!r}')
        self.ft_cutoff = None if ft_cutoff is None else float(ft_cutoff)
        self.k_null = float(k_null)
        self.ik_damping = float(ik_damping)
        self.ik_singular_value = float(ik_singular_value)
        self.ik_max_damping = float(ik_max_damping)
        if not float(limit_margin) >= 0:
            raise ParameterError(f'limit_margin must be >= 0 rad, got {limit_margin!r}')
        self.limit_margin = float(limit_margin)
        self.chains = []

    def setup(self, sim):
        """Set the servo gains and bind the chains to sites."""
        m = sim.model
        kp, kd = self.joint_gains
        for a in sim.actuator_ids:
            m.actuator_gainprm[a, 0] = kp
            m.actuator_biasprm[a, :3] = (0.0, -kp, -kd)
        self.chains = []
        dt = sim.dt
        for chain, adm in self.admittance.items():
            mass, damping, stiffness = (_params(getattr(adm, what), chain, what) for what in
                                        ('mass', 'damping', 'stiffness'))
            denom = mass + dt * damping + dt * dt * stiffness
            if np.any(mass + damping <= 0):
                raise ParameterError(f"admittance of chain '{chain}': M_x and D_x are both 0 "
                                     f'on axes {np.nonzero(mass + damping <= 0)[0].tolist()}; '
                                     'give every axis a mass or a damping > 0')
            self.chains.append(_Chain(name=chain, site_id=sim.site_id(chain), mass=mass,
                                      damping=damping, stiffness=stiffness, denom=denom))
        self._alpha = 1.0 if self.ft_cutoff is None else \
            1.0 - np.exp(-2.0 * np.pi * self.ft_cutoff * dt)
        self._ki_limit = self.joint_ki_limit * np.asarray(sim.robot.tau_max, dtype=float)
        q_min = np.asarray(sim.robot.q_min, dtype=float)
        q_max = np.asarray(sim.robot.q_max, dtype=float)
        span = q_max - q_min
        margin = np.minimum(self.limit_margin, 0.1 * np.where(np.isfinite(span), span, np.inf))
        self._q_lo, self._q_hi = q_min + margin, q_max - margin
        n = len(sim.joint_names)
        self._jacp = np.zeros((3, m.nv))
        self._jacr = np.zeros((3, m.nv))
        self._jac = np.zeros((6 * len(self.chains), n))
        self._err = np.zeros(6 * len(self.chains))
        self._eye_n = np.eye(n)
        self._eye_m = np.eye(6 * len(self.chains))
        self.q_ref = np.zeros(n)
        self._q_prev = np.zeros(n)
        self.q_v = np.zeros(n)
        self.tau_i = np.zeros(n)

    def reset(self, sim, q0):
        """Start at rest at ``q0``: x_d = FK(q0), Δx = 0."""
        self.q_ref = np.array(q0, dtype=float)
        self._q_prev = self.q_ref.copy()
        self.q_v = self.q_ref.copy()
        self.tau_i = np.zeros(len(self.q_ref))
        sim.data.ctrl[sim.actuator_index] = self.q_ref
        self._set_desired(sim, self.q_v)
        for c in self.chains:
            c.dx[:] = 0.0
            c.dxd[:] = 0.0
            c.h_f = None  # the filter starts at the first reading

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
            if c.h_f is None:
                c.h_f = h.copy()
            else:
                c.h_f += self._alpha * (h - c.h_f)
            c.dxd[:] = (c.mass * c.dxd + dt * (c.h_f - c.stiffness * c.dx)) / c.denom
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
        jjt = jac @ jac.T
        lam2 = self.ik_damping ** 2
        sigma2 = np.linalg.eigvalsh(jjt)[0]  # smallest singular value squared
        if sigma2 < self.ik_singular_value ** 2:
            lam2 += self.ik_max_damping ** 2 * (1.0 - max(sigma2, 0.0)
                                                / self.ik_singular_value ** 2)
        pinv = jac.T @ np.linalg.inv(jjt + lam2 * self._eye_m)
        null = self._eye_n - pinv @ jac
        self.q_ref += self.ik_gain * (pinv @ self._err) + null @ (
            (self.k_null * dt) * (self.q_v - self.q_ref))
        # Into the limits, but never jump: a reference already beyond one is held there.
        np.clip(self.q_ref, np.minimum(self._q_lo, self._q_prev),
                np.maximum(self._q_hi, self._q_prev), out=self.q_ref)
        self._q_prev[:] = self.q_ref
        d.ctrl[sim.actuator_index] = self.q_ref
        if self.joint_ki:
            self.tau_i += (self.joint_ki * dt) * (self.q_ref - d.qpos[sim.qpos_index])
            np.clip(self.tau_i, -self._ki_limit, self._ki_limit, out=self.tau_i)
        d.qfrc_applied[sim.dof_index] = d.qfrc_bias[sim.dof_index] + self.tau_i


def _params(value, chain, what):
    a = np.asarray(value, dtype=float).reshape(-1).copy()
    if a.shape != (6,) or not np.all(np.isfinite(a)) or np.any(a < 0):
        raise ParameterError(f"admittance {what} of chain '{chain}' must be 6 finite numbers "
                             f'>= 0, got {value!r}')
    return a
