"""The task-stack language: YAML/JSON task stacks, trajectories, validation and building.

::

    from ifc_spg.task_stack import TaskStack, TaskStackError
    stack = TaskStack.from_yaml(text)   # frozen specs; raises TaskStackError
    tasks = stack.build(robot)          # validated against the robot, then built
"""

from ifc_spg.task_stack.errors import TaskStackError
from ifc_spg.task_stack.loader import MAX_TEXT_BYTES
from ifc_spg.task_stack.spec import (
    MAX_DIM,
    MAX_TASKS,
    TASK_TYPES,
    TRAJECTORIES,
    VERSION,
    BoundSpec,
    SubspaceSpec,
    TaskSpec,
)
from ifc_spg.task_stack.task_stack import TaskStack
from ifc_spg.task_stack.trajectories import Anchor, Circle, Ramp, Sine, SquareWave

__all__ = [
    'MAX_DIM',
    'MAX_TASKS',
    'MAX_TEXT_BYTES',
    'TASK_TYPES',
    'TRAJECTORIES',
    'VERSION',
    'Anchor',
    'BoundSpec',
    'Circle',
    'Ramp',
    'Sine',
    'SquareWave',
    'SubspaceSpec',
    'TaskSpec',
    'TaskStack',
    'TaskStackError',
]
