"""rosbag2 MCAP bags: write, read, record over DDS, play back, summarise (``ifc-spg bag``).

The command line (parser, output, exit status) around :mod:`ifc_spg.offline.bag` (bags on
disk: ``info``) and :mod:`ifc_spg.live.bag` (over DDS: ``record``, ``play``).
"""

import argparse
from collections.abc import Sequence
import sys

from ifc_spg.errors import IfcSpgError
from ifc_spg.live.bag import play, record
from ifc_spg.offline.bag import info

__all__ = ['main']


def main(argv: Sequence[str] | None = None) -> int:
    """``ifc-spg bag record|play|info``."""
    argv = list(sys.argv[1:] if argv is None else argv)
    ros_args = []
    if '--ros-args' in argv:
        i = argv.index('--ros-args')
        argv, ros_args = argv[:i], argv[i:]
    parser = argparse.ArgumentParser(prog='ifc-spg bag', description=__doc__.split('\n')[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest='cmd', required=True)
    r = sub.add_parser('record', help='record topics over DDS into a new bag')
    r.add_argument('topics', nargs='*', help='topics (default: the product topics)')
    r.add_argument('-o', '--output', required=True, help='bag directory to create')
    r.add_argument('-a', '--all', action='store_true', help='also record discovered topics')
    r.add_argument('--duration', type=float, default=None, help='stop after S seconds')
    r.add_argument('--robot', default=None,
                   help='robot of /robot_description and /tf (default: the one spg/config '
                        'or spg/status names)')
    r.add_argument('--no-tf', action='store_true',
                   help='no /robot_description, /tf_static, /tf')
    p = sub.add_parser('play', help='publish a bag with its original timing and QoS')
    p.add_argument('bag')
    p.add_argument('--rate', type=float, default=1.0, help='playback speed factor')
    p.add_argument('--delay', type=float, default=0.5, help='wait S seconds for discovery')
    p.add_argument('--topics', nargs='*', default=None, help='only these topics')
    p.add_argument('--wait-for-subscribers', type=int, default=0, metavar='N',
                   help='after --delay, wait (up to 30 s) until every topic has N matched '
                        'subscriptions (discovery can take seconds)')
    info_parser = sub.add_parser('info', help='topics, types, counts, duration')
    info_parser.add_argument('bag')
    opts = parser.parse_args(argv)
    try:
        if opts.cmd == 'info':
            print(info(opts.bag))
        elif opts.cmd == 'record':
            record(opts.output, opts.topics or None, opts.all, opts.duration, ros_args,
                   robot=opts.robot, foxglove=not opts.no_tf)
        else:
            counts = play(opts.bag, opts.rate, opts.delay, opts.topics, ros_args,
                          wait_subscribers=opts.wait_for_subscribers)
            print('played ' + ', '.join(f'{t}: {c}' for t, c in counts.items()))
    except IfcSpgError as exc:
        print(f'ifc-spg bag {opts.cmd}: {exc}', file=sys.stderr)
        return 2
    return 0


if __name__ == '__main__':
    sys.exit(main())
