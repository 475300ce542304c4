"""Cartesian pose task on a frame at the virtual configuration (Table 3.1).

alpha = S^T [p_v - p_ref; log3(R_v R_ref^T)] with S in the base frame (an end-effector
subspace is rotated into the base frame at the current virtual pose, 3.25 / Table 4.4).
Positions are absolute (p_ref = 0) unless ``relative=True`` (p_ref = position at
activation); the orientation is always relative to R_ref (default: orientation at
activation; or a fixed rotation). The Jacobian is exact:
A = S^T [J_lin; Jlog3(R_e) R_e^T J_ang], R_e = R_v R_ref^T, with S and R_ref held fixed.

One free rotation (the rotational rows of S span two directions, e.g. a pen whose rotation
about its axis is released, Table 3.4): the rotation about the free axis must not enter
the error, however large it grows. log3(R_v R_ref^T) would mix it into the constrained
components (and is singular at pi), so the reference is turned about the free axis to the
current orientation every tick: R_ref' = M R_v, with M the minimal rotation taking the
free axis of the current frame, d_v = R_v a, onto the reference's, d_ref = R_ref a
(end-effector subspaces; for a free base axis, the same in body coordinates). The error
R_v R_ref'^T = M^T is then the pure tilt between d_ref and d_v, perpendicular to d_v.
"""

from __future__ import annotations

from collections.abc import Sequence
import math
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin

from ifc_spg.errors import IfcSpgError
from ifc_spg.tasks.subspace import cartesian_subspace, selected_rows, subspace_in_base
from ifc_spg.tasks.task import Task

if TYPE_CHECKING:
    from ifc_spg.kinematics import Kinematics
    from ifc_spg.model.robot_model import RobotModel

__all__ = ['CartesianPoseTask', 'minimal_rotation']


class CartesianPoseTask(Task):
    """Pose task of a chain end ("frame").

    Args:
        robot: The :class:`~ifc_spg.model.RobotModel`.
        frame: Chain id (e.g. ``'tool'``).
        axes: Named directions (``x y z rx ry rz``), default all six.
        subspace: Explicit 6 x m matrix with orthonormal columns (instead of ``axes``).
        subspace_frame: 'base', 'ee' or 'ee_orientation'.
        orientation: Reference rotation R_ref (3 x 3) or 'init' (default).
        relative: Positions relative to the position at activation (default False).
        **kwargs: Bounds in [m] / [rad] per direction, gain, feed-forward (see Task).
    """

    kind = 'cartesian_pose'
    has_gamma = False

    def __init__(self, robot: RobotModel, *, frame: str, axes: Sequence[str] | None = None,
                 subspace: Any = None, subspace_frame: str = 'base', orientation: Any = 'init',
                 relative: bool = False, **kwargs: Any) -> None:
        self.frame = frame
        self.frame_id = robot.frame_id(frame)
        S = cartesian_subspace(axes, subspace, subspace_frame)
        self.S = S
        self.subspace_frame = subspace_frame
        if isinstance(orientation, str):
            if orientation != 'init':
                raise IfcSpgError(f"orientation must be 'init' or a rotation matrix, got "
                                  f'{orientation!r}')
            self._R_ref: np.ndarray | None = None
            self._orientation_init = True
        else:
            R = np.asarray(orientation, dtype=float)
            if R.shape != (3, 3) or np.abs(R.T @ R - np.eye(3)).max() > 1e-6 \
                    or np.linalg.det(R) < 0:
                raise IfcSpgError('orientation must be a 3 x 3 rotation matrix')
            self._R_ref = R
            self._orientation_init = False
        self.relative = bool(relative)
        self._p_ref = np.zeros(3)
        self.free_axis = _free_rotation_axis(S)
        self._rotational = bool(np.any(S[3:] != 0.0))
        self._translational = bool(np.any(S[:3] != 0.0))
        # the full pose in base coordinates (the most common case): St @ x is x itself
        self._full_base = subspace_frame == 'base' and S.shape == (6, 6) and \
            bool(np.array_equal(S, np.eye(6)))
        # base axes (the other common case): St @ x is x[rows]
        self._rows = selected_rows(S, subspace_frame)
        self._rot_rows = None if self._rows is None else self._rows - 3
        # rx ry rz in order: the rotation error and its Jacobian are the task's as they are
        self._rot_all = self._rows is not None and bool(np.array_equal(self._rows, [3, 4, 5]))
        super().__init__(robot, dim=S.shape[1], **kwargs)
        self._zero = np.zeros(self.dim)
        self._zero.setflags(write=False)

    @property
    def reference_rotation(self) -> np.ndarray | None:
        """R_ref (3 x 3, read-only), or None until activation captures it (``'init'``)."""
        if self._R_ref is None:
            return None
        view = self._R_ref.view()
        view.setflags(write=False)
        return view

    _value_is_computed = True

    def _capture(self, kin: Kinematics) -> None:
        """Capture R_ref (``'init'``) and p_ref (``relative``) before the ``init`` bounds."""
        p, R, _ = kin.frame(self.frame_id, virtual=True)
        if self._R_ref is None:
            self._R_ref = R.copy()
        if self.relative:
            self._p_ref = p.copy()

    def deactivate(self) -> None:
        """Also forget R_ref captured at activation (``'init'``): a restart captures it anew."""
        super().deactivate()
        if self._orientation_init:
            self._R_ref = None

    def _S_base(self, R: np.ndarray) -> np.ndarray:
        return subspace_in_base(self.S, self.subspace_frame, R)

    def reference_orientation(self, R: np.ndarray) -> np.ndarray:
        """R_ref used at the current orientation R (turned about a free axis, if any).

        Before activation (``orientation='init'``) R_ref is taken as R itself.
        """
        R_ref = R if self._R_ref is None else self._R_ref
        a = self.free_axis
        if a is None:
            return R_ref
        if self.subspace_frame == 'base':  # free rotation about the base axis a
            return R @ minimal_rotation(R.T @ a, R_ref.T @ a).T
        return minimal_rotation(R @ a, R_ref @ a) @ R

    def compute(self, kin: Kinematics) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return ``(alpha, A, 0)`` in one computation (gamma is zero: a position task)."""
        p, R, J = kin.frame(self.frame_id, virtual=True)
        if self._R_ref is None:
            self._R_ref = R.copy()
        if self._full_base:
            return (*kin.kernels.pose_error(p, self._p_ref, R, self._reference(R), J),
                    self._zero)
        rows = self._rows
        if rows is not None:
            if not self._rotational:
                return (p - self._p_ref)[rows], J[rows], self._zero
            if not self._translational:
                e_rot, J_rot = kin.kernels.pose_error(None, None, R, self._reference(R), J)
                if self._rot_all:
                    return e_rot, J_rot, self._zero
                return e_rot[self._rot_rows], J_rot[self._rot_rows], self._zero
            x, Jx = kin.kernels.pose_error(p, self._p_ref, R, self._reference(R), J)
            return x[rows], Jx[rows], self._zero
        St = self._S_base(R).T
        if not self._rotational:  # position rows only: the orientation error is not needed
            return St[:, :3].dot(p - self._p_ref), St[:, :3].dot(J[:3]), self._zero
        if not self._translational:
            e_rot, J_rot = kin.kernels.pose_error(None, None, R, self._reference(R), J)
            return St[:, 3:].dot(e_rot), St[:, 3:].dot(J_rot), self._zero
        x, Jx = kin.kernels.pose_error(p, self._p_ref, R, self._reference(R), J)
        return St.dot(x), St.dot(Jx), self._zero

    def _reference(self, R: np.ndarray) -> np.ndarray:
        """R_ref of the rotation error R_e = R R_ref^T at the current orientation R.

        The error and its Jacobian are the kernels' ``pose_error`` (pinocchio's log3, Jlog3).
        """
        R_ref = self._R_ref
        if R_ref is None or self.free_axis is not None:
            R_ref = self.reference_orientation(R)
        return R_ref

    def compute_value(self, kin: Kinematics) -> np.ndarray:
        """The task value S^T [p_v - p_ref; log3(R_v R_ref^T)]."""
        return self.compute(kin)[0]

    def compute_jacobian(self, kin: Kinematics) -> np.ndarray:
        """A = S^T [J_lin; Jlog3(R_e) R_e^T J_ang] (S and R_ref held fixed)."""
        return self.compute(kin)[1]

    def compute_measured_rate(self, kin: Kinematics) -> np.ndarray:
        """S^T J(q) qdot: the task-space velocity of the measured motion."""
        _, R, J = kin.frame(self.frame_id, virtual=False)
        return self._S_base(kin.frame(self.frame_id, virtual=True)[1]).T.dot(J.dot(kin.qdot))


def _free_rotation_axis(S: np.ndarray) -> np.ndarray | None:
    """The unit free rotation axis if the rotational rows of S span exactly two directions."""
    rot = S[3:]
    if np.linalg.matrix_rank(rot, tol=1e-9) != 2:
        return None
    u, _, _ = np.linalg.svd(rot)
    return u[:, 2].copy()


def minimal_rotation(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The rotation of least angle taking unit vector u onto unit vector v."""
    # (3-vector algebra in Python floats: np.cross costs ~20 us per call)
    u0, u1, u2 = u.tolist()
    v0, v1, v2 = v.tolist()
    axis = np.array([u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0])
    s = math.sqrt(axis @ axis)
    c = u0 * v0 + u1 * v1 + u2 * v2
    if s < 1e-12:
        if c > 0:
            return np.eye(3)
        perp = np.cross(u, [1.0, 0.0, 0.0] if abs(u0) < 0.9 else [0.0, 1.0, 0.0])
        return pin.exp3(np.pi * perp / np.linalg.norm(perp))
    axis *= math.atan2(s, c) / s
    return pin.exp3(axis)
