"""Static interaction quantities: replacement task variables of IFC robots (docs/SPEC.md §1).

Joint impedance (tau = K (q_v - q) - D qdot + ...)::

    tau_s = K (q_v - q),            A = K,           gamma = K qdot
    h_s = J^{+T} K (q_v - q),       A = J^{+T} K,    gamma = J^{+T} K qdot

with J = J(q) at the measured configuration (damped pseudo-inverse) and stiff joints
(position controlled) contributing no static torque (their K and J columns are zero).

Cartesian admittance (h = K_x dx + ...), our generalisation (docs/SPEC.md §1)::

    h_s = K_x [p_v - p; log3(R_v R^T)],   tau_s = J^T h_s.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from ifc_spg.errors import IfcSpgError
from ifc_spg.model import JOINT_IMPEDANCE

if TYPE_CHECKING:
    from ifc_spg.kinematics import Kinematics
    from ifc_spg.model.robot_model import RobotModel

__all__ = ['DAMPING', 'load_lapack', 'static_torque', 'static_wrench', 'check_admittance_chain']

#: LAPACK's Cholesky solver (scipy's dposv), loaded by :func:`load_lapack`.
_LAPACK: dict = {}


def load_lapack():
    """Import scipy's LAPACK solver the static wrench uses; return it.

    Importing ``scipy.linalg`` costs 0.16-0.18 s of CPU, so this module does not do it on
    import: processes that parse task stacks but never compute a wrench (``task_publisher``)
    skip it. :mod:`ifc_spg.spg` calls it on import, so an SPG's first tick does not pay it.
    """
    if not _LAPACK:
        from scipy.linalg.lapack import dposv
        _LAPACK['dposv'] = dposv
    return _LAPACK['dposv']

DAMPING = 1e-3  # lambda of the damped pseudo-inverse J^{+T} = (J J^T + lambda^2 I)^{-1} J


_DAMPING_EYE = DAMPING ** 2 * np.eye(6)
_DAMPING_EYE.setflags(write=False)


def compliant_stiffness(robot: RobotModel) -> np.ndarray:
    """Per-joint stiffness with zeros at stiff (position-controlled) joints, in [Nm/rad]."""
    return robot.compliant_stiffness


def compliant_damping(robot: RobotModel) -> np.ndarray:
    """Per-joint damping with zeros at stiff (position-controlled) joints, in [Nms/rad]."""
    return robot.compliant_damping


def check_admittance_chain(robot: RobotModel, frame: str) -> None:
    """Raise unless ``frame`` has Cartesian admittance parameters."""
    if frame not in robot.admittance:
        raise IfcSpgError(f"frame '{frame}' of admittance robot '{robot.name}' has no "
                          'admittance parameters (K_x); use one of: '
                          f"{', '.join(sorted(robot.admittance))}")


def _admittance_wrench(robot: RobotModel, kin: Kinematics,
                       frame: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    fid = robot.frame_id(frame)
    p_v, R_v, J_v = kin.frame(fid, virtual=True)
    p, R, J = kin.frame(fid, virtual=False)
    Kx = robot.admittance[frame].stiffness
    R_e = R_v.dot(R.T)  # (ndarray.dot: half the overhead of @ on small operands)
    Jl = pin.Jlog3(R_e)
    x = np.concatenate([p_v - p, pin.log3(R_e)])
    A = np.vstack([J_v[:3], Jl.dot(R_e.T).dot(J_v[3:])])
    v = J.dot(kin.qdot)
    g = np.concatenate([v[:3], Jl.dot(v[3:])])
    return Kx * x, Kx[:, None] * A, Kx * g, J


def static_wrench(robot: RobotModel, kin: Kinematics, frame: str, include_damping: bool = False
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return ``(h_s (6,), A (6, n), gamma (6,), R (3, 3))`` of chain ``frame`` in base frame.

    R is the measured orientation of the frame (used for end-effector subspaces). With
    ``include_damping`` the joint-impedance value also holds the damping torque of the
    measured motion, h_s = J^{+T} (K (q_v - q) - D qdot): the wrench the IFC actually
    applies while moving (A and gamma are unchanged: qdot does not depend on qdot_v).
    """
    fid = robot.frame_id(frame)
    _, R, J = kin.frame(fid, virtual=False)
    if robot.ifc != JOINT_IMPEDANCE:
        h, A, g, _ = _admittance_wrench(robot, kin, frame)
        return h, A, g, R
    K = robot.compliant_stiffness
    Jc = J * robot.compliant_columns
    # J^{+T} = (Jc Jc^T + lambda^2 I)^{-1} Jc: symmetric positive definite, so LAPACK's
    # Cholesky solver (dposv; a third of np.linalg.solve's cost here)
    _, P, info = (_LAPACK.get('dposv') or load_lapack())(Jc.dot(Jc.T) + _DAMPING_EYE, Jc)
    if info != 0:  # not positive definite: only with non-finite measurements
        P = np.linalg.solve(Jc @ Jc.T + _DAMPING_EYE, Jc)
    PK = P * K
    tau = K * (kin.q_v - kin.q)
    if include_damping:
        tau = tau - robot.compliant_damping * kin.qdot
    return P.dot(tau), PK, PK.dot(kin.qdot), R


def static_torque(robot: RobotModel, kin: Kinematics, include_damping: bool = False
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return ``(tau_s (n,), A (n, n), gamma (n,))``; see :func:`static_wrench` for damping."""
    if robot.ifc == JOINT_IMPEDANCE:
        K = robot.compliant_stiffness
        tau = K * (kin.q_v - kin.q)
        if include_damping:
            tau = tau - robot.compliant_damping * kin.qdot
        return tau, np.diag(K), K * kin.qdot
    n = robot.n
    tau, A, g = np.zeros(n), np.zeros((n, n)), np.zeros(n)
    for frame in robot.admittance:
        h, Ah, gh, J = _admittance_wrench(robot, kin, frame)
        tau += J.T.dot(h)
        A += J.T.dot(Ah)
        g += J.T.dot(gh)
    return tau, A, g
