"""The four task archetypes of Table 3.1, their bounds and subspaces."""

from ifc_spg.tasks.bounds import INIT, Bound, Constant, Init
from ifc_spg.tasks.cartesian_pose_task import CartesianPoseTask
from ifc_spg.tasks.joint_position_task import JointPositionTask
from ifc_spg.tasks.joint_torque_task import JointTorqueTask
from ifc_spg.tasks.task import Level, Task
from ifc_spg.tasks.wrench_task import WrenchTask

__all__ = ['INIT', 'Bound', 'CartesianPoseTask', 'Constant', 'Init', 'JointPositionTask',
           'JointTorqueTask', 'Level', 'Task', 'WrenchTask']
