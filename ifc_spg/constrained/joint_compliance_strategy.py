"""Joint-compliance strategy (thesis 5.4, eqs. 5.7-5.11): a set-point generator of its own.

Per tick, with J = J(q) of the interaction frame at the measured q::

    delta_q_exp = K^-1 J^T [kappa d_hat; 0] dT                                  (5.7)
    d_q = norm(delta_q_exp),  P_q = d_q d_q^T                                  (5.8)
    q_v[i+1] = q[i] + P_q (q_v[i] - q[i]) + delta_q_exp + delta_q_o            (5.9/5.11)
    delta_q_o = J_v^+ [0; omega_d] dT                                          (5.10)

The projection keeps the static torque K (q_v - q) along K d_q, i.e. the static wrench
along [d_hat; 0]: erroneous forces and all moments are cancelled every tick. The
orientation term omega_d is ``fixed`` (back to the initial orientation with gain k_o),
``align_z`` (z_ee towards -d_hat), ``release_y`` (only about x_ee) or ``free`` (0).
"""

import math

import numpy as np
import pinocchio as pin

from ifc_spg.constrained.direction_estimator import DirectionEstimator
from ifc_spg.constrained.params import StrategyParams
from ifc_spg.errors import IfcSpgError, ParameterError
from ifc_spg.kinematics import Kinematics
from ifc_spg.model import JOINT_IMPEDANCE
from ifc_spg.tasks.static_interaction import DAMPING, compliant_stiffness

__all__ = ['JointComplianceStrategy', 'orientation_rate']


def orientation_rate(mode, R_v, R_init, d_hat, gain):
    """Desired angular velocity omega_d in [rad/s] (base frame) of an orientation mode.

    Args:
        mode: 'free', 'fixed', 'align_z' or 'release_y'.
        R_v: Current (virtual) end-effector rotation.
        R_init: Rotation at the start (``fixed``).
        d_hat: Estimated direction of motion.
        gain: k_o in [1/s].
    """
    if mode == 'fixed':
        return gain * pin.log3(R_init @ R_v.T)
    if mode == 'free':
        return np.zeros(3)
    omega = -gain * np.cross(R_v[:, 2], d_hat)
    if mode == 'release_y':
        x = R_v[:, 0]
        return (x @ omega) * x
    return omega


class JointComplianceStrategy:
    """The joint-level constrained manipulation strategy of Sec. 5.4.

    Args:
        robot: A joint-impedance :class:`~ifc_spg.model.RobotModel` (its K is used).
        params: :class:`~ifc_spg.constrained.params.StrategyParams` (kappa, dt, orientation,
            orientation_gain, max_force, estimator).
        frame: Chain id of the interaction point.
        estimator: Direction estimator (default: one built from ``params.estimator``).

    Attributes:
        estimator: The direction estimator; ``estimator.direction`` is d_hat.
        q_v: The last set-point in [rad].
    """

    name = 'joint_compliance'

    def __init__(self, robot, params=None, *, frame='tool', estimator=None):
        if robot.ifc != JOINT_IMPEDANCE:
            raise ParameterError(f"the joint-compliance strategy needs a joint-impedance robot; "
                                 f"'{robot.name}' is {robot.ifc} (use the admittance strategy)")
        self.robot = robot
        self.params = params or StrategyParams()
        self.frame = frame
        self.frame_id = robot.frame_id(frame)
        self.estimator = estimator or DirectionEstimator(self.params.estimator)
        self.kin = Kinematics(robot)
        self._K = compliant_stiffness(robot)
        self._Kinv = np.where(self._K > 0, 1.0 / np.where(self._K > 0, self._K, 1.0), 0.0)
        self.q_v = None
        self._R_init = None
        self._t = None

    def reset(self, q):
        """Start at the measured q: q_v = q, the initial orientation is captured."""
        q = np.asarray(q, dtype=float)
        self.q_v = np.clip(q, self.robot.q_min, self.robot.q_max)
        self.kin.update(q, np.zeros(self.robot.n), self.q_v)
        self._R_init = self.kin.frame(self.frame_id, virtual=False)[1].copy()

    def step(self, q, qdot, t):
        """One tick: returns the new q_v in [rad] (a new array)."""
        q = np.asarray(q, dtype=float)
        qdot = np.asarray(qdot, dtype=float)
        if self.q_v is None:
            self.reset(q)
        if self.q_v is None:  # set by reset
            raise IfcSpgError('internal: q_v is unset after reset')
        p = self.params
        kin = self.kin
        kin.update(q, qdot, self.q_v)
        _, _, J = kin.frame(self.frame_id, virtual=False)
        d = self.estimator.update(J[:3] @ qdot, stamp=t)
        dq = self.q_v - q
        kappa = p.kappa
        if math.isfinite(p.max_force) and float(d @ self.static_force()) >= p.max_force:
            kappa = 0.0
        step_dir = self._Kinv * (J[:3].T @ d)  # K^-1 J^T [d; 0]
        norm = float(np.linalg.norm(step_dir))
        if norm > 1e-12:
            d_q = step_dir / norm
            dq = d_q * float(d_q @ dq)
        dq_exp = (kappa * p.dt) * step_dir
        dq_o = 0.0
        if p.orientation != 'free':
            _, R_v, J_v = kin.frame(self.frame_id, virtual=True)
            omega = orientation_rate(p.orientation, R_v, self._R_init, d, p.orientation_gain)
            # J_v^+ [0; omega] with the damped pseudo-inverse J^T (J J^T + l^2 I)^-1.
            rhs = np.zeros(6)
            rhs[3:] = omega * p.dt
            dq_o = J_v.T @ np.linalg.solve(J_v @ J_v.T + DAMPING ** 2 * np.eye(6), rhs)
        self.q_v = np.clip(q + dq + dq_exp + dq_o, self.robot.q_min, self.robot.q_max)
        return self.q_v.copy()

    def static_force(self):
        """Static force f_s = [J^{+T} K (q_v - q)]_{1:3} in [N] of the current tick."""
        kin = self.kin
        _, _, J = kin.frame(self.frame_id, virtual=False)
        tau = self._K * (kin.q_v - kin.q)
        return np.linalg.solve(J @ J.T + DAMPING ** 2 * np.eye(6), J @ tau)[:3]
