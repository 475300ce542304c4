"""Joint position task: alpha = q_v (selected joints), A = rows of I_n, gamma = 0 (Table 3.1)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from ifc_spg.tasks.task import Task

if TYPE_CHECKING:
    from ifc_spg.kinematics import Kinematics
    from ifc_spg.model.robot_model import RobotModel

__all__ = ['JointPositionTask', 'joint_indices']


def joint_indices(robot: RobotModel, joints: Sequence[str] | None,
                  exclude_stiff: bool = False) -> np.ndarray:
    """Indices of ``joints`` (names) in q; all joints (optionally without stiff ones) if None."""
    if joints is None:
        idx = [i for i in range(robot.n) if not (exclude_stiff and robot.stiff_mask[i])]
    else:
        idx = [robot.joint_index(j) for j in joints]
    return np.array(idx, dtype=int)


class JointPositionTask(Task):
    """Joint position task on a subset of joints.

    Args:
        robot: The :class:`~ifc_spg.model.RobotModel`.
        joints: Joint names (default: all joints, in model order).
        **kwargs: Bounds, gain and feed-forward, see :class:`~ifc_spg.tasks.task.Task`;
            values in [rad] (prismatic: [m]).
    """

    kind = 'joint_position'
    has_gamma = False

    def __init__(self, robot: RobotModel, *, joints: Sequence[str] | None = None,
                 **kwargs: Any) -> None:
        self.indices = joint_indices(robot, joints)
        super().__init__(robot, dim=len(self.indices), **kwargs)
        self._A = np.zeros((self.dim, robot.n))
        self._A[np.arange(self.dim), self.indices] = 1.0
        self._A.setflags(write=False)
        self._zero = np.zeros(self.dim)
        self._zero.setflags(write=False)

    _value_is_computed = True

    def compute(self, kin: Kinematics) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return ``(q_v[i], A, 0)`` in one computation (gamma is zero: a position task)."""
        return kin.q_v[self.indices], self._A, self._zero

    def compute_value(self, kin: Kinematics) -> np.ndarray:
        """The virtual positions of the selected joints, q_v[i]."""
        return kin.q_v[self.indices]

    def compute_jacobian(self, kin: Kinematics) -> np.ndarray:
        """The selected rows of the identity (constant, read-only)."""
        return self._A

    def compute_measured_rate(self, kin: Kinematics) -> np.ndarray:
        """The measured velocities of the selected joints, qdot[i]."""
        return kin.qdot[self.indices]
