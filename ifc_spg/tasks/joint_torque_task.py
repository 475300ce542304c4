"""Joint torque task: alpha = tau_s (selected joints), A = K, gamma = K qdot (Table 3.1)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from ifc_spg.errors import IfcSpgError
from ifc_spg.model import JOINT_IMPEDANCE
from ifc_spg.tasks.joint_position_task import joint_indices
from ifc_spg.tasks.static_interaction import static_torque
from ifc_spg.tasks.task import Task

if TYPE_CHECKING:
    from ifc_spg.kinematics import Kinematics
    from ifc_spg.model.robot_model import RobotModel

__all__ = ['JointTorqueTask']


class JointTorqueTask(Task):
    """Static joint torque task tau_s = K (q_v - q) on a subset of joints.

    Args:
        robot: The :class:`~ifc_spg.model.RobotModel`.
        joints: Joint names (default: all compliant joints). Stiff joints have no static
            torque and are rejected.
        include_damping: The value includes the IFC damping of the measured motion,
            tau_s = K (q_v - q) - D qdot (the thesis' static value omits -D qdot).
        **kwargs: Bounds in [Nm], gain, feed-forward (see Task).
    """

    kind = 'joint_torque'

    def __init__(self, robot: RobotModel, *, joints: Sequence[str] | None = None,
                 include_damping: bool = False, **kwargs: Any) -> None:
        self.include_damping = bool(include_damping)
        self.indices = joint_indices(robot, joints, exclude_stiff=True)
        stiff = [robot.joint_names[i] for i in self.indices if robot.stiff_mask[i]]
        if stiff:
            raise IfcSpgError(f"joint_torque task: joint(s) {', '.join(stiff)} are stiff "
                              '(position controlled) and have no static torque; remove them')
        super().__init__(robot, dim=len(self.indices), **kwargs)
        self._fast = robot.ifc == JOINT_IMPEDANCE
        if self._fast:  # tau_s = K (q_v - q) on the selected joints: A is constant
            K = robot.stiffness[self.indices]
            self._K = K
            self._D = robot.damping[self.indices]
            A = np.zeros((self.dim, robot.n))
            A[np.arange(self.dim), self.indices] = K
            A.setflags(write=False)
            self._A = A
        # all joints in model order (the usual case): no index arrays
        self._all = bool(np.array_equal(self.indices, np.arange(robot.n)))

    _value_is_computed = True

    def compute(self, kin: Kinematics) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return ``(tau_s, A, gamma)`` of the selected joints in one computation."""
        i = self.indices
        if self._fast and self._all:
            tau = self._K * (kin.q_v - kin.q)
            if self.include_damping:
                tau -= self._D * kin.qdot
            return tau, self._A, self._K * kin.qdot
        if self._fast:
            tau = self._K * (kin.q_v[i] - kin.q[i])
            if self.include_damping:
                tau -= self._D * kin.qdot[i]
            return tau, self._A, self._K * kin.qdot[i]
        tau, A, g = static_torque(self.robot, kin, self.include_damping)
        return tau[i], A[i], g[i]

    def compute_value(self, kin: Kinematics) -> np.ndarray:
        """The static torque tau_s of the selected joints in [Nm]."""
        return self.compute(kin)[0]

    def compute_jacobian(self, kin: Kinematics) -> np.ndarray:
        """A = d(tau_s)/d(q_v) of the selected joints (K on their columns)."""
        return self.compute(kin)[1]

    def compute_gamma(self, kin: Kinematics) -> np.ndarray:
        """Gamma = K qdot of the selected joints (Table 3.1)."""
        return self.compute(kin)[2]
