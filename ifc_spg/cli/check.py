"""``ifc-spg check FILE...``: validate task-stack files against their robot model.

Each file is parsed and validated against the robot its ``robot:`` field names (or
``--robot NAME``). Exit status 0 when every file is valid, 2 when any is not (or on a usage
error); one line per file on stdout (``ok``) or stderr (the error: file, line, column,
field path, reason). ``--print`` writes the normalized stack (every field explicit).
"""

import argparse
import sys

import yaml

from ifc_spg.errors import IfcSpgError
from ifc_spg.model import RobotModel
from ifc_spg.task_stack.errors import TaskStackError
from ifc_spg.task_stack.task_stack import TaskStack

__all__ = ['main']


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog='ifc-spg check', description=__doc__.split('\n\n')[0].split(': ', 1)[1],
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('files', nargs='+', metavar='FILE', help='task-stack files (.yaml/.json)')
    p.add_argument('--robot', metavar='NAME',
                   help="robot model to check against (overrides the files' robot: field); "
                        'lbr4, lbr_iiwa14, icub_upper_body, accrea_dual_arm')
    p.add_argument('--print', dest='print_stack', action='store_true',
                   help='print the normalized stack of each valid file')
    p.add_argument('--format', choices=('yaml', 'json'), default='yaml',
                   help='format of --print (default yaml)')
    return p


def _robot(name: str, cache: dict[str, RobotModel]) -> RobotModel:
    if name not in cache:
        cache[name] = RobotModel.from_config(name)
    return cache[name]


def main(argv: list[str] | None = None) -> int:
    """Run the check; returns the exit status (0 valid, 2 invalid)."""
    try:
        args = _parser().parse_args(argv)
    except SystemExit as exc:
        return 0 if exc.code == 0 else 2
    cache: dict[str, RobotModel] = {}
    if args.robot is not None:
        try:
            _robot(args.robot, cache)
        except IfcSpgError as exc:
            print(f'ifc-spg check: {exc}', file=sys.stderr)
            return 2
    status = 0
    for path in args.files:
        try:
            stack = TaskStack.from_file(path)
            name = args.robot or stack.robot
            if name is None:
                raise TaskStackError("no robot to check against: add 'robot: NAME' to the "
                                     'file or pass --robot NAME', source=path)
            try:
                robot = _robot(name, cache)
            except IfcSpgError as exc:
                raise stack.error(('robot',), str(exc)) from None
            stack.validate(robot)
        except TaskStackError as exc:
            print(exc if exc.source else exc.with_source(path), file=sys.stderr)
            status = 2
            continue
        note = '' if stack.robot in (None, name) else f' (written for {stack.robot})'
        print(f'{path}: ok: {len(stack.tasks)} tasks, robot {name}{note}')
        if args.print_stack:
            data = stack.to_dict()
            if args.format == 'json':
                print(stack.to_json())
            else:
                print(yaml.safe_dump(data, sort_keys=False, default_flow_style=None), end='')
    return status


if __name__ == '__main__':
    sys.exit(main())
