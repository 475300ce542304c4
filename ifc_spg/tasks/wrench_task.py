"""Wrench task: alpha = S^T h_s at a chain end, A = S^T J^{+T} K, gamma = S^T J^{+T} K qdot."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from ifc_spg.model import JOINT_IMPEDANCE
from ifc_spg.tasks.static_interaction import check_admittance_chain, static_wrench
from ifc_spg.tasks.subspace import cartesian_subspace, selected_rows, subspace_in_base
from ifc_spg.tasks.task import Task

if TYPE_CHECKING:
    from ifc_spg.kinematics import Kinematics
    from ifc_spg.model.robot_model import RobotModel

__all__ = ['WrenchTask']


class WrenchTask(Task):
    """Static wrench task (force the robot exerts on the environment, base frame).

    Args:
        robot: The :class:`~ifc_spg.model.RobotModel`.
        frame: Chain id (e.g. ``'tool'``).
        axes: Named directions (``fx fy fz tx ty tz``), default all six.
        subspace: Explicit 6 x m matrix with orthonormal columns (instead of ``axes``).
        subspace_frame: 'base', 'ee' or 'ee_orientation' (measured end-effector frame).
        include_damping: The value includes the IFC damping of the measured motion,
            h_s = J^{+T} (K (q_v - q) - D qdot) (the force actually applied while moving;
            the thesis' static value omits -D qdot). Joint impedance only.
        **kwargs: Bounds in [N] / [Nm], gain, feed-forward (see Task).
    """

    kind = 'wrench'

    def __init__(self, robot: RobotModel, *, frame: str, axes: Sequence[str] | None = None,
                 subspace: Any = None, subspace_frame: str = 'base',
                 include_damping: bool = False, **kwargs: Any) -> None:
        self.frame = frame
        self.include_damping = bool(include_damping)
        robot.frame_id(frame)
        if robot.ifc != JOINT_IMPEDANCE:
            check_admittance_chain(robot, frame)
        S = cartesian_subspace(axes, subspace, subspace_frame, wrench=True)
        self.S = S
        self.subspace_frame = subspace_frame
        super().__init__(robot, dim=S.shape[1], **kwargs)
        self._rows = selected_rows(S, subspace_frame)  # base axes: St @ x is x[rows]

    _value_is_computed = True

    def compute(self, kin: Kinematics) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return ``(S^T h_s, S^T A, S^T gamma)`` in one computation."""
        h, A, g, R = static_wrench(self.robot, kin, self.frame, self.include_damping)
        rows = self._rows
        if rows is not None:
            return h[rows], A[rows], g[rows]
        St = subspace_in_base(self.S, self.subspace_frame, R).T
        return St.dot(h), St.dot(A), St.dot(g)

    def compute_value(self, kin: Kinematics) -> np.ndarray:
        """The static wrench in the subspace, S^T h_s, in [N] / [Nm]."""
        return self.compute(kin)[0]

    def compute_jacobian(self, kin: Kinematics) -> np.ndarray:
        """A = S^T J^{+T} K (S held fixed)."""
        return self.compute(kin)[1]

    def compute_gamma(self, kin: Kinematics) -> np.ndarray:
        """Gamma = S^T J^{+T} K qdot (Table 3.1)."""
        return self.compute(kin)[2]
