"""ifc_spg: set-point generation for robots under indirect force control.

Top-level API::

    from ifc_spg import RobotModel, TaskStack, SetPointGenerator

The names are imported on first use (PEP 562), so that ``import ifc_spg.<module>`` of a light
module (the console entry points, the ROS layer, the errors) does not load pinocchio.
"""

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ifc_spg.errors import (
        IfcSpgError,
        ModelError,
        UnknownFrame,
        UnknownJoint,
        UnknownRobot,
    )
    from ifc_spg.model import RobotModel
    from ifc_spg.spg import SetPointGenerator
    from ifc_spg.task_stack import TaskStack, TaskStackError

_WHERE = {
    'IfcSpgError': 'ifc_spg.errors',
    'ModelError': 'ifc_spg.errors',
    'RobotModel': 'ifc_spg.model',
    'SetPointGenerator': 'ifc_spg.spg',
    'TaskStack': 'ifc_spg.task_stack',
    'TaskStackError': 'ifc_spg.task_stack',
    'UnknownFrame': 'ifc_spg.errors',
    'UnknownJoint': 'ifc_spg.errors',
    'UnknownRobot': 'ifc_spg.errors',
}
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


def __getattr__(name: str) -> Any:
    """Import a top-level name from its module on first use."""
    if name in _WHERE:
        value = getattr(importlib.import_module(_WHERE[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'ifc_spg' has no attribute {name!r}")


def __dir__() -> list[str]:
    """The module's names, the lazily imported ones included."""
    return sorted(list(globals()) + list(_WHERE))
