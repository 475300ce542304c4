"""The ``task_publisher``: publish task-stack files on ``spg/task_stack`` (latched).

    task_publisher STACK.yaml                       # one stack, latched, until Ctrl-C
    task_publisher a.yaml b.yaml@5 c.yaml@12.5      # a timed sequence [s after start]
    task_publisher STACK.yaml --once                # deliver to a subscriber, then exit
    task_publisher STACK.yaml --linger 3 --robot lbr_iiwa14 --ros-args -r __ns:=/arm

Every file is validated first, as ``ifc-spg check`` does and with its error lines (file,
line, column, field path, reason): against the robot of ``--robot`` or of the file's
``robot:`` field (frames, joints, dimensions), else by format only. Any invalid file:
nothing is published, exit code 2.

``FILE@T`` publishes FILE T seconds (wall clock) after the start; a file without ``@T``
is published at 0. The start is when publishing begins, i.e. after ``--wait-subscribers``
subscriptions matched (``--once`` waits for one). The topic is transient local (depth 1),
so a node that starts later still gets the latest stack; the publisher stays alive to keep
it available until Ctrl-C / SIGTERM, ``--linger SECONDS`` after the last publication, or
with ``--once`` until the subscribers acknowledged the last stack. The message is the
file's text as is (YAML or JSON).

Exit codes: 0 done, 1 no subscriber in time (``--once`` / ``--wait-subscribers``),
2 invalid file or arguments.
"""

import argparse
import signal
import sys
import time

from ifc_spg import ros
from ifc_spg.errors import IfcSpgError
from ifc_spg.model import RobotModel
from ifc_spg.ros.msg import String
from ifc_spg.task_stack import TaskStack, TaskStackError

__all__ = ['main', 'parse_entry', 'load_entries']


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


def _parser():
    """The command-line parser (the ROS arguments removed first)."""
    p = argparse.ArgumentParser(
        prog='task_publisher', description='Publish task-stack files (latched).',
        epilog='ROS arguments go after --ros-args (remaps, namespace).')
    p.add_argument('files', nargs='+', metavar='FILE[@SECONDS]',
                   help='task-stack file, optionally with its publication time in [s]')
    p.add_argument('--topic', default='spg/task_stack', help='topic (default: %(default)s)')
    p.add_argument('--robot', default=None,
                   help="validate against this robot (default: the file's robot: field)")
    p.add_argument('--once', action='store_true',
                   help='exit once a subscriber acknowledged the last stack')
    p.add_argument('--linger', type=float, default=None, metavar='SECONDS',
                   help='exit this long after the last publication')
    p.add_argument('--wait-subscribers', type=int, default=None, metavar='N',
                   help='wait for N subscriptions before starting (default 0; --once: 1)')
    p.add_argument('--timeout', type=float, default=30.0, metavar='SECONDS',
                   help='give up waiting for subscribers after this long (default 30)')
    return p


def _wait(condition, timeout, ok):
    """Poll ``condition`` until it holds, ``timeout`` [s] passed or ``ok()`` is False."""
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline or not ok():
            return bool(condition())
        time.sleep(0.02)
    return True


def main(argv=None):
    """Entry point of the ``task_publisher`` executable; returns the exit code."""
    argv = list(sys.argv if argv is None else argv)
    user = ros.remove_ros_args(argv)[1:]
    parser = _parser()
    try:
        args = parser.parse_args(user)
    except SystemExit as exc:
        return int(exc.code or 0)
    if args.linger is not None and not args.linger >= 0:
        print('task_publisher: --linger must be >= 0 seconds', file=sys.stderr)
        return 2
    try:
        entries = load_entries(args.files, args.robot)
    except IfcSpgError as exc:
        print(exc if isinstance(exc, TaskStackError) else f'task_publisher: {exc}',
              file=sys.stderr)
        return 2
    stop = []

    def on_signal(signum, frame):
        stop.append(signum)

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    ros.init(args=argv)
    node = ros.Node('task_publisher')
    node.get_logger().info(f'task_publisher: {ros.describe()}')
    try:
        return _publish(node, args, entries, alive=lambda: not stop)
    finally:
        node.destroy_node()
        if ros.ok():
            ros.shutdown()
        for s, handler in previous.items():
            signal.signal(s, handler)


def _publish(node, args, entries, alive):
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


if __name__ == '__main__':
    sys.exit(main())
