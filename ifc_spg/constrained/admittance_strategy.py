"""Cartesian-admittance strategy (thesis 5.3, eq. 5.6) for the ACCREA interface.

Per tick, with p, R the measured pose of the interaction frame (FK of the measured q)::

    p_v := p_v + nu d_hat dT                 exploration along the estimate   (5.3.1)
    p_v := p + P_hat (p_v - p)               cancel erroneous forces          (5.6)

The admittance makes the force K_x (p_v - p) point along p_v - p, so the force builds up
along d_hat at K_x nu [N/s] until the mechanism moves. Orientation: ``fixed`` (R_v =
R_init), ``free`` (R_v = R, no moment), ``align_z`` / ``release_y`` (R_v turned by the
rate of 5.20). The interface takes joint set-points, so x_v = (p_v, R_v) is mapped to q_v
by damped Gauss-Newton IK on the robot model, warm-started from the previous q_v (the
chain's Jacobian has zero columns for the other arm, which keeps its q_v).
"""

import math

import numpy as np
import pinocchio as pin

from ifc_spg.constrained.direction_estimator import DirectionEstimator
from ifc_spg.constrained.joint_compliance_strategy import orientation_rate
from ifc_spg.constrained.params import StrategyParams
from ifc_spg.errors import ParameterError
from ifc_spg.kinematics import Kinematics

__all__ = ['CartesianAdmittanceStrategy', 'solve_ik']

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def solve_ik(robot, data, frame_id, q, p_target, R_target, iterations=3, damping=1e-3):
    """Damped Gauss-Newton IK from ``q`` towards (p_target [m], R_target); returns q [rad].

    The error is [p_target - p; log3(R_target R^T)] (base frame), the step
    J^T (J J^T + damping^2 I)^-1 e, clipped into the joint limits.
    """
    q = np.array(q, dtype=float)
    eye = np.eye(6)
    for _ in range(iterations):
        pin.framesForwardKinematics(robot.model, data, q)
        oMf = data.oMf[frame_id]
        e = np.concatenate([p_target - oMf.translation, pin.log3(R_target @ oMf.rotation.T)])
        J = pin.computeFrameJacobian(robot.model, data, q, frame_id, _LWA)
        J[3:] = pin.Jlog3(R_target @ oMf.rotation.T) @ J[3:]
        q = np.clip(q + J.T @ np.linalg.solve(J @ J.T + damping ** 2 * eye, e), robot.q_min,
                    robot.q_max)
    return q


class CartesianAdmittanceStrategy:
    """The original strategy of Sec. 5.3 on a Cartesian admittance robot.

    Args:
        robot: The :class:`~ifc_spg.model.RobotModel` (any; on a joint-impedance robot the
            set-point is a position target, not a force, see Sec. 5.4).
        params: :class:`~ifc_spg.constrained.params.StrategyParams` (nu, dt, orientation,
            orientation_gain, max_force, estimator).
        frame: Chain id of the interaction point (default: the first admittance chain).
        estimator: Direction estimator (default: from ``params.estimator``).
        ik_iterations: Gauss-Newton iterations per tick.

    Attributes:
        estimator: The direction estimator.
        p_v: Virtual position in [m]; R_v: virtual rotation.
        q_v: The last set-point in [rad].
    """

    name = 'admittance'

    def __init__(self, robot, params=None, *, frame=None, estimator=None, ik_iterations=3):
        self.robot = robot
        self.params = params or StrategyParams()
        if frame is None:
            frame = next(iter(robot.admittance), 'tool')
        self.frame = frame
        self.frame_id = robot.frame_id(frame)
        self.estimator = estimator or DirectionEstimator(self.params.estimator)
        adm = robot.admittance.get(frame)
        k_x = None if adm is None else float(np.min(np.asarray(adm.stiffness)[:3]))
        self.max_deflection = math.inf if k_x is None or not k_x > 0 \
            else self.params.max_force / k_x
        if ik_iterations < 1:
            raise ParameterError(f'ik_iterations must be >= 1, got {ik_iterations}')
        self.ik_iterations = int(ik_iterations)
        self.kin = Kinematics(robot)
        self._data = robot.create_data()
        self.q_v = None
        self.p_v = None
        self.R_v = None
        self._R_init = None

    def reset(self, q):
        """Start at the measured q: x_v = FK(q)."""
        q = np.asarray(q, dtype=float)
        self.q_v = np.clip(q, self.robot.q_min, self.robot.q_max)
        self.kin.update(q, np.zeros(self.robot.n), self.q_v)
        p, R, _ = self.kin.frame(self.frame_id, virtual=False)
        self.p_v, self.R_v, self._R_init = p.copy(), R.copy(), R.copy()

    def step(self, q, qdot, t):
        """One tick: returns the new q_v in [rad] (a new array)."""
        q = np.asarray(q, dtype=float)
        qdot = np.asarray(qdot, dtype=float)
        if self.q_v is None:
            self.reset(q)
        prm = self.params
        self.kin.update(q, qdot, self.q_v)
        p, R, J = self.kin.frame(self.frame_id, virtual=False)
        d = self.estimator.update(J[:3] @ qdot, stamp=t)
        p_v = self.p_v + (prm.nu * prm.dt) * d
        along = float(d @ (p_v - p))
        along = min(along, self.max_deflection)
        self.p_v = p + along * d
        if prm.orientation == 'free':
            self.R_v = R.copy()
        elif prm.orientation != 'fixed':
            omega = orientation_rate(prm.orientation, self.R_v, self._R_init, d,
                                     prm.orientation_gain)
            self.R_v = pin.exp3(omega * prm.dt) @ self.R_v
        self.q_v = solve_ik(self.robot, self._data, self.frame_id, self.q_v, self.p_v,
                            self.R_v, iterations=self.ik_iterations)
        return self.q_v.copy()
