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
from collections.abc import Sequence
import signal
import sys
from types import FrameType

from ifc_spg import ros
from ifc_spg.errors import IfcSpgError
from ifc_spg.node.task_publisher import load_entries, publish_entries
from ifc_spg.task_stack import TaskStackError

__all__ = ['main']


def _parser() -> argparse.ArgumentParser:
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


def main(argv: Sequence[str] | None = None) -> int:
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

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.append(signum)

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    ros.init(args=argv)
    node = ros.Node('task_publisher')
    node.get_logger().info(f'task_publisher: {ros.describe()}')
    try:
        return publish_entries(node, args, entries, alive=lambda: not stop)
    finally:
        node.destroy_node()
        if ros.ok():
            ros.shutdown()
        for s, handler in previous.items():
            signal.signal(s, handler)


if __name__ == '__main__':
    sys.exit(main())
