"""Joint position task: alpha = q_v (selected joints), A = rows of I_n, gamma = 0 (Table 3.1)."""

import numpy as np

from ifc_spg.tasks.task import Task

__all__ = ['JointPositionTask', 'joint_indices']


def joint_indices(robot, joints, exclude_stiff=False):
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

    def __init__(self, robot, *, joints=None, **kwargs):
        self.indices = joint_indices(robot, joints)
        super().__init__(robot, dim=len(self.indices), **kwargs)
        self._A = np.zeros((self.dim, robot.n))
        self._A[np.arange(self.dim), self.indices] = 1.0
        self._A.setflags(write=False)

    def compute_value(self, kin):
        return kin.q_v[self.indices]

    def compute_jacobian(self, kin):
        return self._A

    def compute_measured_rate(self, kin):
        return kin.qdot[self.indices]
