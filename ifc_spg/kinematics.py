"""Per-tick kinematics at the measured and the virtual configuration.

One :class:`Kinematics` object is owned by a :class:`~ifc_spg.spg.SetPointGenerator`; it
owns two pinocchio ``Data`` (measured q, virtual q_v) and caches frame quantities for the
current tick so that several tasks on the same frame share one computation (docs/STYLE.md rule 7).
All Jacobians are 6 x n, LOCAL_WORLD_ALIGNED: linear velocity of the frame origin and
angular velocity, both in the base frame (docs/SPEC.md, Notation).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from ifc_spg import kernels as _kernels

if TYPE_CHECKING:
    from types import ModuleType

    from ifc_spg.model.robot_model import RobotModel

#: A frame's ``(position (3,), rotation (3, 3), jacobian (6, n))``.
FrameQuantities = tuple[np.ndarray, np.ndarray, np.ndarray]

__all__ = ['Kinematics']

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


class Kinematics:
    """Kinematic quantities of one tick.

    Args:
        robot: The :class:`~ifc_spg.model.RobotModel`.
        kernels: The kernels of the tasks' arithmetic on these quantities (default
            :data:`ifc_spg.kernels.active`; the SPG passes its own).
    """

    def __init__(self, robot: RobotModel, kernels: ModuleType | None = None) -> None:
        self.robot = robot
        #: the kernels the tasks use on this tick's quantities (e.g. ``pose_error``)
        self.kernels = _kernels.resolve(kernels)
        self._model = robot.model
        self._data_v = robot.create_data()
        self._data_m = robot.create_data()
        n = robot.n
        self.q = np.zeros(n)
        self.qdot = np.zeros(n)
        self.q_v = np.zeros(n)
        self._cache_v: dict[int, FrameQuantities] = {}
        self._cache_m: dict[int, FrameQuantities] = {}
        self._valid_v = False
        self._valid_m = False

    def update(self, q: np.ndarray, qdot: np.ndarray, q_v: np.ndarray) -> None:
        """Set the configuration of this tick (arrays are copied; nothing is computed yet).

        Args:
            q: Measured joint positions in [rad].
            qdot: Measured joint velocities in [rad/s].
            q_v: Virtual (commanded) joint positions in [rad].
        """
        self.q[:] = q
        self.qdot[:] = qdot
        self.q_v[:] = q_v
        self._cache_v.clear()
        self._cache_m.clear()
        self._valid_v = False
        self._valid_m = False

    def _ensure(self, virtual: bool) -> None:
        # one pass for all joints' placements and Jacobians; a frame's placement is updated
        # when it is asked for (frame()): a robot has hundreds of frames (iCub: 432), a
        # stack uses a few
        if virtual and not self._valid_v:
            pin.computeJointJacobians(self._model, self._data_v, self.q_v)
            self._valid_v = True
        elif not virtual and not self._valid_m:
            pin.computeJointJacobians(self._model, self._data_m, self.q)
            self._valid_m = True

    def data(self, virtual: bool) -> pin.Data:
        """The pinocchio ``Data`` of q_v (True) or q with joint placements and Jacobians.

        Read only: it is shared by the tasks of this tick. Its ``oMf`` holds this tick's
        placement only of the frames asked for with :meth:`frame`.
        """
        self._ensure(virtual)
        return self._data_v if virtual else self._data_m

    def frame(self, frame_id: int, virtual: bool) -> FrameQuantities:
        """Return ``(position (3,), rotation (3, 3), jacobian (6, n))`` of a frame.

        Args:
            frame_id: pinocchio frame id.
            virtual: True for the virtual configuration q_v, False for the measured q.
        """
        cache = self._cache_v if virtual else self._cache_m
        hit = cache.get(frame_id)
        if hit is None:
            self._ensure(virtual)
            data = self._data_v if virtual else self._data_m
            # (one 4 x 4 copy out of pinocchio and two contiguous copies: ~0.9 us less than
            # copying translation and rotation out one by one)
            H = pin.updateFramePlacement(self._model, data, frame_id).homogeneous
            J = pin.getFrameJacobian(self._model, data, frame_id, _LWA)
            hit = (H[:3, 3].copy(), H[:3, :3].copy(), J)
            cache[frame_id] = hit
        return hit
