"""ifc_spg: set-point generation for robots under indirect force control.

Top-level API::

    from ifc_spg import RobotModel, TaskStack, SetPointGenerator
"""

from ifc_spg.errors import IfcSpgError, ModelError, UnknownFrame, UnknownJoint, UnknownRobot
from ifc_spg.model import RobotModel
from ifc_spg.spg import SetPointGenerator
from ifc_spg.task_stack import TaskStack, TaskStackError

__all__ = [
    'IfcSpgError',
    'ModelError',
    'RobotModel',
    'SetPointGenerator',
    'TaskStack',
    'TaskStackError',
    'UnknownFrame',
    'UnknownJoint',
    'UnknownRobot',
]
__version__ = '0.1.0'
