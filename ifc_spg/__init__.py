"""ifc_spg: set-point generation for robots under indirect force control.

Top-level API::

    from ifc_spg import RobotModel, TaskStack, SetPointGenerator
"""

from ifc_spg.errors import IfcSpgError, ModelError, UnknownFrame, UnknownJoint, UnknownRobot
from ifc_spg.model import RobotModel

__all__ = [
    'IfcSpgError',
    'ModelError',
    'RobotModel',
    'UnknownFrame',
    'UnknownJoint',
    'UnknownRobot',
]
__version__ = '0.1.0'
