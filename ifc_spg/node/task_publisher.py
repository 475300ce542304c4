"""Task-stack files for ``spg/task_stack``: read, validate, publish them on a node in time.

The library of the ``task_publisher`` executable (its command line:
:mod:`ifc_spg.cli.task_publisher`): :func:`load_entries` reads and validates ``FILE[@T]``
entries as ``ifc-spg check`` does, :func:`publish_entries` publishes them latched at their
times and keeps them available as the command line asks.
"""

import time

from ifc_spg import ros
from ifc_spg.errors import IfcSpgError
from ifc_spg.model import RobotModel
from ifc_spg.ros.msg import String
from ifc_spg.task_stack import TaskStack, TaskStackError

__all__ = ['load_entries', 'parse_entry', 'publish_entries']


def parse_entry(text):
    """Split ``FILE@SECONDS`` into (file, seconds); a plain FILE is at 0 s.

    Raises:
        IfcSpgError: A negative or non-numeric time.
    """
    path, sep, when = text.rpartition('@')
    if not sep:
        return text, 0.0
    try:
        seconds = float(when)
    except ValueError:
        raise IfcSpgError(f"'{text}': the time after '@' must be seconds, e.g. "
                          f"'{path}@2.5'") from None
    if not seconds >= 0 or seconds == float('inf'):
        raise IfcSpgError(f"'{text}': the time after '@' must be a finite number >= 0 s")
    return path, seconds


def load_entries(entries, robot=None):
    """Read and validate every ``FILE[@T]``; return [(t, file, text, stack name)] by time.

    Files are parsed as ``ifc-spg check`` does (``TaskStack.from_file``) and validated
    against ``robot``, else the robot the file names (``robot:``), else by format only
    (the SPG checks it against its robot when it arrives).

    Args:
        entries: Command-line entries.
        robot: Robot configuration name to validate against (None: the file's).

    Raises:
        IfcSpgError: The first invalid file; a TaskStackError reads
            ``FILE (line L, column C): tasks[2].frame: reason`` as in ``ifc-spg check``.
    """
    models = {}
    out = []
    for i, entry in enumerate(entries):
        path, t = parse_entry(entry)
        try:
            stack = TaskStack.from_file(path)
            name = robot or stack.robot
            if name:
                if name not in models:
                    try:
                        models[name] = RobotModel.from_config(name)
                    except IfcSpgError as exc:
                        if robot:
                            raise
                        raise stack.error(('robot',), str(exc)) from None
                stack.validate(models[name])
        except TaskStackError as exc:
            raise (exc if exc.source else exc.with_source(path)) from None
        with open(path, encoding='utf-8') as f:
            text = f.read()
        out.append((t, i, path, text, stack.name or path))
    out.sort()
    return [(t, path, text, name) for t, _, path, text, name in out]


def _wait(condition, timeout, ok):
    """Poll ``condition`` until it holds, ``timeout`` [s] passed or ``ok()`` is False."""
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline or not ok():
            return bool(condition())
        time.sleep(0.02)
    return True


def publish_entries(node, args, entries, alive):
    """Publish ``entries`` on ``node`` as ``args`` ask; the exit code.

    Args:
        node: The node to publish from.
        args: The parsed command line.
        entries: [(t, file, text, stack name)] of :func:`load_entries`.
        alive: ``alive()`` is False once a signal asked to stop.
    """
    log = node.get_logger()
    wait_subs = args.wait_subscribers if args.wait_subscribers is not None else \
        (1 if args.once else 0)
    pub = node.create_publisher(String, args.topic, ros.latched(1))
    if wait_subs and not _wait(lambda: pub.get_subscription_count() >= wait_subs,
                               args.timeout, alive):
        if not alive():
            return 0
        log.error(f'no {wait_subs} subscriber(s) on {pub.topic_name} after '
                  f'{args.timeout} s; nothing published')
        return 1
    start = time.monotonic()
    for t, path, text, name in entries:
        if not _wait(lambda t=t: time.monotonic() - start >= t, t + 1.0, alive):
            return 0
        pub.publish(String(data=text))
        log.info(f"published '{path}' (stack '{name}') on {pub.topic_name} at "
                 f'+{time.monotonic() - start:.3f} s')
    if args.once:
        ros.wait_for_acks(pub, args.timeout)
        return 0
    linger = float('inf') if args.linger is None else args.linger
    end = time.monotonic() + linger
    _wait(lambda: time.monotonic() >= end, linger + 1.0 if linger < 1e9 else 1e12, alive)
    return 0
