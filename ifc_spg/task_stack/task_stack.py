"""TaskStack: the user's task language (YAML or JSON), parsed once into frozen specs.

::

    stack = TaskStack.from_file('config/tasks/table_3_2_surface_tracking.yaml')
    stack.validate(robot)          # frames, joints, dimensions (raises TaskStackError)
    tasks = stack.build(robot)     # fresh task objects, highest priority first
    spg.set_stack(stack)           # hot swap: builds, then switches at the next tick

The order of ``tasks`` is the priority (first = highest). See docs/ARCHITECTURE.md
"Task stack" and ``ifc_spg/schema/task_stack.schema.json``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import json
import os
from typing import TYPE_CHECKING, Any

from ifc_spg.task_stack.builder import build_tasks
from ifc_spg.task_stack.errors import TaskStackError
from ifc_spg.task_stack.loader import MAX_TEXT_BYTES, Document, load
from ifc_spg.task_stack.spec import VERSION, parse_document, task_to_data

if TYPE_CHECKING:
    from ifc_spg.model.robot_model import RobotModel
    from ifc_spg.tasks.task import Task

__all__ = ['TaskStack']


@dataclass(frozen=True)
class TaskStack:
    """A parsed, immutable task stack.

    Attributes:
        name: Stack name.
        tasks: Tuple of :class:`~ifc_spg.task_stack.spec.TaskSpec`, highest priority first.
        robot: Name of the robot model the stack is written for (a hint), or None.
        description: Free text, or None.
        power_budget: Refill rate of the PSPM energy tanks in [W] the stack asks for (its
            author knows it does work on the environment: slides a tool, lifts a drawer);
            None: strictly passive. The SPG rejects a stack asking for more than its
            ``pspm.max_power``.
        obstacles: Tuple of :class:`~ifc_spg.task_stack.collision.ObstacleSpec` (the
            ``obstacles:`` that ``collision_avoidance`` tasks keep the robot from).
        version: Format version (1).
        source: Where the text came from (file name), or None.
    """

    name: str
    tasks: tuple
    robot: str | None = None
    description: str | None = None
    power_budget: float | None = None
    obstacles: tuple = ()
    version: int = VERSION
    source: str | None = field(default=None, compare=False)
    _doc: Document | None = field(default=None, compare=False, repr=False)

    # -- construction ------------------------------------------------------------------
    @classmethod
    def _from(cls, text: str | bytes, fmt: str, source: str | None) -> TaskStack:
        doc = load(text, fmt, source)
        return cls._from_document(doc)

    @classmethod
    def _from_document(cls, doc: Document) -> TaskStack:
        kw = parse_document(doc)
        return cls(name=kw['name'], tasks=kw['tasks'], robot=kw['robot'],
                   description=kw['description'], power_budget=kw['power_budget'],
                   obstacles=kw['obstacles'], version=kw['version'], source=doc.source,
                   _doc=doc)

    @classmethod
    def from_yaml(cls, text: str | bytes, source: str | None = None) -> TaskStack:
        """Parse YAML text (raises :class:`TaskStackError`)."""
        return cls._from(text, 'yaml', source)

    @classmethod
    def from_json(cls, text: str | bytes, source: str | None = None) -> TaskStack:
        """Parse JSON text (raises :class:`TaskStackError`)."""
        return cls._from(text, 'json', source)

    @classmethod
    def from_text(cls, text: str | bytes, source: str | None = None) -> TaskStack:
        """Parse YAML or JSON text, detected from the text (JSON if it starts with '{')."""
        return cls._from(text, 'auto', source)

    @classmethod
    def from_dict(cls, data: Any, source: str | None = None) -> TaskStack:
        """Build from plain data (as loaded from YAML/JSON; no source positions).

        The data goes through the same checks as text (size, depth, finite numbers).
        """
        try:
            text = json.dumps(data, allow_nan=False)
        except (TypeError, ValueError) as exc:
            raise TaskStackError(f'data is not plain JSON-like data: {exc}',
                                 source=source) from None
        except RecursionError:
            raise TaskStackError('data nested too deeply', source=source) from None
        return cls._from(text, 'json', source)

    @classmethod
    def from_file(cls, path: str | os.PathLike[str]) -> TaskStack:
        """Read a ``.yaml`` / ``.yml`` / ``.json`` file (format by extension, else detected)."""
        path = os.fspath(path)
        try:
            size = os.path.getsize(path)
            if size > MAX_TEXT_BYTES:
                raise TaskStackError(f'file is {size} bytes, more than the limit of '
                                     f'{MAX_TEXT_BYTES} bytes (256 KiB)', source=path)
            with open(path, 'rb') as f:
                data = f.read(MAX_TEXT_BYTES + 1)
        except OSError as exc:
            raise TaskStackError(f'cannot read file: {exc.strerror or exc}',
                                 source=path) from None
        ext = os.path.splitext(path)[1].lower()
        fmt = {'.json': 'json', '.yaml': 'yaml', '.yml': 'yaml'}.get(ext, 'auto')
        return cls._from(data, fmt, path)

    # -- use ---------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The normalized stack as plain data (every field explicit, defaults filled in).

        ``TaskStack.from_dict(stack.to_dict())`` equals ``stack``.
        """
        out: dict[str, Any] = {'version': self.version, 'name': self.name}
        if self.robot is not None:
            out['robot'] = self.robot
        if self.description is not None:
            out['description'] = self.description
        if self.power_budget is not None:
            out['power_budget'] = self.power_budget
        if self.obstacles:
            from ifc_spg.task_stack.collision import obstacle_to_data
            out['obstacles'] = [obstacle_to_data(o) for o in self.obstacles]
        out['tasks'] = [task_to_data(t) for t in self.tasks]
        return out

    def to_json(self, indent: int | None = 2) -> str:
        """The normalized stack as JSON text."""
        return json.dumps(self.to_dict(), indent=indent)

    def validate(self, robot: RobotModel) -> None:
        """Check the stack against ``robot`` (frames, joints, dimensions, limits).

        Tasks are built on trial (and discarded), so a stack that validates also builds.
        A ``constrained_manipulation`` task is checked without its module if that module
        is not installed.

        Raises:
            TaskStackError: Naming the path (``tasks[2].frame``), line and column.
        """
        build_tasks(self, robot, construct='available')

    def build(self, robot: RobotModel) -> list[Task]:
        """Validate and build fresh task objects for ``robot``, highest priority first.

        ``init`` values are captured when the tasks become active (first SPG tick).

        Raises:
            TaskStackError: As :meth:`validate`; also if a task type is not available.
        """
        return build_tasks(self, robot, construct=True)

    @property
    def document(self) -> Document | None:
        """The loaded text: its data as written, with source positions (None if built directly)."""
        return self._doc

    def error(self, path: tuple, reason: str) -> TaskStackError:
        """Return a :class:`TaskStackError` at field ``path`` (e.g. ``('robot',)``).

        The error names the field and, where the stack came from text, its line and column.
        """
        if self._doc is None:
            return TaskStackError(reason, path, source=self.source)
        return self._doc.error(path, reason)

    def __len__(self) -> int:
        return len(self.tasks)
