"""Wrench task: alpha = S^T h_s at a chain end, A = S^T J^{+T} K, gamma = S^T J^{+T} K qdot."""

import numpy as np

from ifc_spg.errors import IfcSpgError
from ifc_spg.model import JOINT_IMPEDANCE
from ifc_spg.tasks.static_interaction import check_admittance_chain, static_wrench
from ifc_spg.tasks.subspace import SUBSPACE_FRAMES, axes_matrix, check_orthonormal
from ifc_spg.tasks.subspace import subspace_in_base
from ifc_spg.tasks.task import Task

__all__ = ['WrenchTask']


class WrenchTask(Task):
    """Static wrench task (force the robot exerts on the environment, base frame).

    Args:
        robot: The :class:`~ifc_spg.model.RobotModel`.
        frame: Chain id (e.g. ``'tool'``).
        axes: Named directions (``fx fy fz tx ty tz``), default all six.
        subspace: Explicit 6 x m matrix with orthonormal columns (instead of ``axes``).
        subspace_frame: 'base', 'ee' or 'ee_orientation' (measured end-effector frame).
        **kwargs: Bounds in [N] / [Nm], gain, feed-forward (see Task).
    """

    kind = 'wrench'

    def __init__(self, robot, *, frame, axes=None, subspace=None, subspace_frame='base',
                 **kwargs):
        self.frame = frame
        robot.frame_id(frame)
        if robot.ifc != JOINT_IMPEDANCE:
            check_admittance_chain(robot, frame)
        if subspace is not None and axes is not None:
            raise IfcSpgError("give either 'axes' or an explicit 'subspace', not both")
        S = axes_matrix(axes or ('fx', 'fy', 'fz', 'tx', 'ty', 'tz'), wrench=True) \
            if subspace is None else check_orthonormal(np.asarray(subspace, dtype=float))
        if S.shape[0] != 6:
            raise IfcSpgError(f'a wrench subspace has 6 rows (fx fy fz tx ty tz), got {S.shape[0]}')
        if subspace_frame not in SUBSPACE_FRAMES:
            raise IfcSpgError(f"subspace frame '{subspace_frame}' unknown; use one of "
                              f"{', '.join(SUBSPACE_FRAMES)}")
        self.S = S
        self.subspace_frame = subspace_frame
        super().__init__(robot, dim=S.shape[1], **kwargs)

    def compute(self, kin):
        h, A, g, R = static_wrench(self.robot, kin, self.frame)
        St = subspace_in_base(self.S, self.subspace_frame, R).T
        return St @ h, St @ A, St @ g

    def compute_value(self, kin):
        return self.compute(kin)[0]

    def compute_jacobian(self, kin):
        return self.compute(kin)[1]

    def compute_gamma(self, kin):
        return self.compute(kin)[2]
