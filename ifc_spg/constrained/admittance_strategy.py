"""Cartesian-admittance strategy (thesis 5.3, eq. 5.6) for the ACCREA interface.

Per tick, with p, R the measured pose of the interaction frame (FK of the measured q)::

    p_v := p_v + nu d_hat dT                 exploration along the estimate   (5.3.1)
    p_v := p + P_hat (p_v - p)               cancel erroneous forces          (5.6)

The admittance makes the force K_x (p_v - p) point along p_v - p, so the force builds up
along d_hat at K_x nu [N/s] until the mechanism moves. Orientation: ``fixed`` (R_v =
R_init), ``free`` (R_v follows R), ``align_z`` / ``release_y`` (R_v turned by the rate of
5.20). The interface takes joint set-points, so x_v = (p_v, R_v) is mapped to q_v by
damped least-squares IK on the robot model (:func:`solve_ik`), warm-started from the
previous q_v, with the joints of the chain only, joint limits enforced by clamping, and a
null-space pull towards the initial posture (gain ``posture_gain``) so that the redundant
arm does not drift towards its limits during a long exploration.

**Relaxed projection on an admittance robot.** On a position-based Cartesian admittance
(``x_c = x_d + Δx``, Δx the integrated admittance state) the instantaneous projection
(5.6) writes the measured pose p ≈ x_c, which already contains Δx, back into x_d every
tick: x_d⊥(k+1) = x_c⊥(k) = x_d⊥(k) + Δx⊥(k), i.e. x_d⊥ integrates Δx⊥ with gain 1/dT.
Against a grasped mechanism (series stiffness K_s of servo, grasp and guide in the
blocked directions) that is the loop ``ẋ_d = Δx / dT``, ``D_x Δẋ = -K_s (x_d + Δx) -
K_x Δx``: a mode at sqrt(K_s dT / D_x) / dT (about 13 Hz for the emulated ACCREA, K_s ~
5e3 N/m) whose only damping is K_x dT / D_x ~ 0.3 % per tick. In closed loop on the
vertical drawer it rang at 13 Hz with ±40 N and, with the joint-limit hit below, blew up
to several hundred N. Here the perpendicular part of p_v - p (and the rotational error of
``free``) therefore relaxes to zero with a time constant τ instead of in one tick::

    p_v := p_v - (1 - exp(-dT / τ)) (I - P_hat)(p_v - p)

which is (5.6) for τ -> 0 and the loop ``ẋ_d = Δx / τ``: s² + s (K_s + K_x) / D_x +
K_s / (D_x τ), damping ratio 0.5 sqrt(K_s τ / D_x) (ignoring M_x). The default τ = D_x /
K_x (the admittance's own time constant, 0.6 s for the ACCREA) gives ζ >= 0.5 for every
environment stiffer than K_x. On a joint-impedance robot (no admittance state) τ = 0,
the thesis' instantaneous projection.

**Without the projection.** ``projection=False`` skips the cancel step (5.6) (the
perpendicular relaxation above), keeping the exploration and the ``max_force`` cap: the
strategy as in thesis Fig. 5.6, where erroneous forces accumulated before the estimate
converged persist.

**Bounded set-point.** With ``max_force`` finite, the deflection along d_hat is capped at
max_force / K_x: exploration stops advancing p_v at the cap (it does not re-anchor p_v on
p, which would again integrate Δx), and a deflection above the cap relaxes back with τ.
"""

import math

import numpy as np
import pinocchio as pin

from ifc_spg.constrained.direction_estimator import DirectionEstimator
from ifc_spg.constrained.joint_compliance_strategy import orientation_rate
from ifc_spg.constrained.params import StrategyParams
from ifc_spg.errors import IfcSpgError, ParameterError
from ifc_spg.kinematics import Kinematics

__all__ = ['LIMIT_MARGIN', 'CartesianAdmittanceStrategy', 'chain_joints', 'solve_ik']

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
#: Default distance [rad] the strategy's IK keeps from the joint position limits (3 deg).
LIMIT_MARGIN = math.radians(3.0)


def chain_joints(robot, frame_id):
    """Boolean mask (n,) of the joints that move frame ``frame_id`` (its kinematic chain)."""
    model = robot.model
    mask = np.zeros(robot.n, dtype=bool)
    for jid in model.supports[model.frames[frame_id].parentJoint]:
        if jid > 0:
            j = model.joints[jid]
            mask[j.idx_v:j.idx_v + j.nv] = True
    return mask


def solve_ik(robot, data, frame_id, q, p_target, R_target, iterations=3, damping=1e-3, *,
             joints=None, q_rest=None, null_gain=0.0, limit_margin=0.0, singular_value=0.05,
             max_damping=0.05):
    """Damped least-squares IK from ``q`` towards (p_target [m], R_target); returns q [rad].

    Per iteration, with the error e = [p_target - p; log3(R_target R^T)] (base frame) and the
    Jacobian J of the ``joints`` (others keep their value)::

        dq = J^T (J J^T + lambda^2 I)^-1 e + (I - J^+ J) null_gain (q_rest - q)

    lambda grows from ``damping`` to ``max_damping`` as the smallest singular value of J
    falls below ``singular_value`` (Maciejewski-Klein damping: bounded steps at
    singularities). Joint limits shrunk by ``limit_margin`` are enforced by clamping: a
    joint that would cross its limit is held at it (never pushed further in, never jumped)
    and the task is re-solved with the remaining joints. The null-space term applies in
    the first iteration only.

    Args:
        robot: The :class:`~ifc_spg.model.RobotModel`.
        data: A pinocchio data of ``robot.model`` (scratch).
        frame_id: Frame id of the controlled frame.
        q: Start configuration in [rad] (n,).
        p_target: Target position in [m] (3,).
        R_target: Target rotation (3, 3).
        iterations: Gauss-Newton iterations.
        damping: Minimal damping lambda.
        joints: Boolean mask (n,) of the joints to use (default: :func:`chain_joints`).
        q_rest: Posture for the null-space term in [rad]; None: no term.
        null_gain: Fraction of (q_rest - q) per call, in [0, 1].
        limit_margin: Distance [rad] kept from the position limits (at most a tenth of
            each joint's range).
        singular_value: Smallest singular value below which the damping grows.
        max_damping: Damping at a singularity.

    Returns:
        The configuration in [rad] (a new array).
    """
    q = np.array(q, dtype=float)
    if joints is None:
        joints = chain_joints(robot, frame_id)
    idx = np.flatnonzero(joints)
    span = robot.q_max - robot.q_min
    margin = np.minimum(limit_margin, 0.1 * np.where(np.isfinite(span), span, np.inf))
    lo, hi = (robot.q_min + margin)[idx], (robot.q_max - margin)[idx]
    for it in range(iterations):
        e, J = _pose_error(robot, data, frame_id, q, p_target, R_target, idx)
        lam2 = _dls_damping(J, damping, singular_value, max_damping)
        z = None
        if it == 0 and q_rest is not None and null_gain > 0:
            z = null_gain * (np.asarray(q_rest, dtype=float)[idx] - q[idx])
        qi = q[idx]
        q[idx] = qi + _clamped_step(J, e, z, qi, lo, hi, lam2)
    return q


def _pose_error(robot, data, frame_id, q, p_target, R_target, idx):
    """Error [p_target - p; log3(R_target R^T)] and its Jacobian in the ``idx`` joints."""
    pin.framesForwardKinematics(robot.model, data, q)
    oMf = data.oMf[frame_id]
    r_err = R_target @ oMf.rotation.T
    e = np.concatenate([p_target - oMf.translation, pin.log3(r_err)])
    J = pin.computeFrameJacobian(robot.model, data, q, frame_id, _LWA)[:, idx]
    J[3:] = pin.Jlog3(r_err) @ J[3:]
    return e, J


def _dls_damping(J, damping, singular_value, max_damping):
    """lambda^2: ``damping``^2, growing towards ``max_damping``^2 near a singularity."""
    sigma = np.linalg.svd(J, compute_uv=False)[-1]
    lam2 = damping ** 2
    if sigma < singular_value:
        lam2 += max_damping ** 2 * (1.0 - (sigma / singular_value) ** 2)
    return lam2


def _clamped_step(J, e, z, qi, lo, hi, lam2):
    """The damped least-squares step from ``qi``, re-solved with joints held at their limits.

    ``z`` (or None) is the null-space motion towards the rest posture.
    """
    eye = np.eye(6)
    free = np.ones(len(qi), dtype=bool)
    dq = np.zeros(len(qi))
    for _ in range(len(qi)):
        Jf = J[:, free]
        rhs = e - J[:, ~free] @ dq[~free]
        pinv = Jf.T @ np.linalg.inv(Jf @ Jf.T + lam2 * eye)
        step = pinv @ rhs
        if z is not None:
            step += z[free] - pinv @ (Jf @ z[free])
        dq[free] = step
        new = qi + dq
        bad = free & ((new < lo) | (new > hi))
        if not bad.any():
            break
        # Hold violators at the limit (or where they are, if already beyond it).
        dq[bad] = np.clip(new[bad], np.minimum(lo, qi)[bad], np.maximum(hi, qi)[bad]) \
            - qi[bad]
        free &= ~bad
        if not free.any():
            break
    return dq


def _admittance_time_constant(adm, rows):
    """max(D_x / K_x) over ``rows`` of an admittance (0 if any K_x is 0: force following)."""
    k = np.asarray(adm.stiffness, dtype=float)[rows]
    d = np.asarray(adm.damping, dtype=float)[rows]
    if np.any(k <= 0):
        return 0.0
    return float(np.max(d / k))


class CartesianAdmittanceStrategy:
    """The original strategy of Sec. 5.3 on a Cartesian admittance robot.

    Args:
        robot: The :class:`~ifc_spg.model.RobotModel` (any; on a joint-impedance robot the
            set-point is a position target, not a force, see Sec. 5.4).
        params: :class:`~ifc_spg.constrained.params.StrategyParams` (nu, dt, orientation,
            orientation_gain, posture_gain, max_force, estimator).
        frame: Chain id of the interaction point (default: the first admittance chain).
        estimator: Direction estimator (default: from ``params.estimator``).
        ik_iterations: IK iterations per tick.
        relax_time: τ [s] of the perpendicular (and ``free`` rotational) relaxation; None:
            D_x / K_x of the chain's admittance (translation; rotation for ``free``), 0 on a
            robot without one (the instantaneous projection 5.6).
        limit_margin: Distance [rad] the IK keeps from the joint position limits.
        projection: Cancel erroneous forces (5.6) (True, default); False: exploration and
            the ``max_force`` cap only, the perpendicular part of p_v - p is kept.

    Attributes:
        estimator: The direction estimator.
        p_v: Virtual position in [m]; R_v: virtual rotation.
        q_v: The last set-point in [rad].
        ik_residual: |x_v - FK(q_v)| of the last tick ([m] and [rad] combined, (6,) norm).
    """

    name = 'admittance'

    def __init__(self, robot, params=None, *, frame=None, estimator=None, ik_iterations=3,
                 relax_time=None, limit_margin=LIMIT_MARGIN, projection=True):
        if not isinstance(projection, bool):
            raise ParameterError(f'projection must be True or False (cancel erroneous forces, '
                                 f'5.6), got {projection!r}')
        self.projection = projection
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
        if relax_time is None:
            tau_p = 0.0 if adm is None else _admittance_time_constant(adm, slice(0, 3))
            tau_r = 0.0 if adm is None else _admittance_time_constant(adm, slice(3, 6))
        else:
            if not (isinstance(relax_time, (int, float)) and relax_time >= 0):
                raise ParameterError(f'relax_time must be a time constant >= 0 s (0: the '
                                     f'instantaneous projection 5.6), got {relax_time!r}')
            tau_p = tau_r = float(relax_time)
        self.relax_time = tau_p
        dt = self.params.dt
        self._relax_p = 1.0 if tau_p <= 0 else -math.expm1(-dt / tau_p)
        self._relax_r = 1.0 if tau_r <= 0 else -math.expm1(-dt / tau_r)
        if not limit_margin >= 0:
            raise ParameterError(f'limit_margin must be >= 0 rad, got {limit_margin!r}')
        self.limit_margin = float(limit_margin)
        self._joints = chain_joints(robot, self.frame_id)
        self.kin = Kinematics(robot)
        self._data = robot.create_data()
        self.q_v = None
        self.p_v = None
        self.R_v = None
        self._R_init = None
        self._q_rest = None
        self.ik_residual = 0.0

    def reset(self, q):
        """Start at the measured q: x_v = FK(q); the posture of q is the IK's rest posture."""
        q = np.asarray(q, dtype=float)
        self.q_v = np.clip(q, self.robot.q_min, self.robot.q_max)
        self._q_rest = self.q_v.copy()
        self.kin.update(q, np.zeros(self.robot.n), self.q_v)
        p, R, _ = self.kin.frame(self.frame_id, virtual=False)
        self.p_v, self.R_v, self._R_init = p.copy(), R.copy(), R.copy()
        self.ik_residual = 0.0

    def step(self, q, qdot, t):
        """One tick: returns the new q_v in [rad] (a new array)."""
        q = np.asarray(q, dtype=float)
        qdot = np.asarray(qdot, dtype=float)
        if self.q_v is None:
            self.reset(q)
        if self.q_v is None or self.p_v is None or self.R_v is None:  # set by reset
            raise IfcSpgError('internal: the virtual state is unset after reset')
        prm = self.params
        self.kin.update(q, qdot, self.q_v)
        p, R, J = self.kin.frame(self.frame_id, virtual=False)
        d = np.array(self.estimator.update(J[:3] @ qdot, stamp=t))
        p_v = self.p_v
        # Exploration (5.3.1), stopped at the deflection cap.
        along = float(d @ (p_v - p))
        p_v = p_v + max(0.0, min(prm.nu * prm.dt, self.max_deflection - along)) * d
        # Cancelling erroneous forces (5.6), relaxed on an admittance robot (module doc).
        e = p_v - p
        along = float(d @ e)
        if self.projection:
            p_v = p_v - self._relax_p * (e - along * d)
        if along > self.max_deflection:
            p_v = p_v - self._relax_p * (along - self.max_deflection) * d
        self.p_v = p_v
        if prm.orientation == 'free':
            self.R_v = pin.exp3(self._relax_r * pin.log3(R @ self.R_v.T)) @ self.R_v
        elif prm.orientation == 'fixed':
            self.R_v = self._R_init
        else:
            omega = orientation_rate(prm.orientation, self.R_v, self._R_init, d,
                                     prm.orientation_gain)
            self.R_v = pin.exp3(omega * prm.dt) @ self.R_v
        self.q_v = solve_ik(self.robot, self._data, self.frame_id, self.q_v, self.p_v,
                            self.R_v, iterations=self.ik_iterations, joints=self._joints,
                            q_rest=self._q_rest, null_gain=prm.posture_gain * prm.dt,
                            limit_margin=self.limit_margin)
        pin.framesForwardKinematics(self.robot.model, self._data, self.q_v)
        oMf = self._data.oMf[self.frame_id]
        self.ik_residual = float(np.linalg.norm(np.concatenate([
            self.p_v - oMf.translation, pin.log3(self.R_v @ oMf.rotation.T)])))
        return self.q_v.copy()
