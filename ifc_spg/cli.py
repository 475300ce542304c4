"""The ``ifc-spg`` tool: demo, run, check, bag, replay, plot, bench, dynamics."""

import argparse
import sys

__all__ = ['main']

_PENDING = {
    'run': 'offline lockstep runner (end-to-end issue)',
    'check': 'task-stack validation (task-stack language issue)',
    'bag': 'rosbag2 MCAP record/play/info (end-to-end issue)',
    'replay': 'recompute SPG output from a bag (end-to-end issue)',
    'plot': 'figures from a bag (end-to-end issue)',
}


def _parser():
    p = argparse.ArgumentParser(
        prog='ifc-spg', description='ifc_spg tool. Verbs marked (pending) are placeholders '
        'that print their usage until their issue lands.')
    sub = p.add_subparsers(dest='verb', metavar='VERB')
    sub.add_parser('demo', help='run the simulated LBR demo')
    sub.add_parser('bench', help='benchmark the SPG tick per solver')
    sub.add_parser('dynamics', help='Popov-Vereshchagin solver scenarios')
    for verb, what in _PENDING.items():
        sub.add_parser(verb, help=f'(pending) {what}')
    return p


def main(argv=None):
    """Entry point of ``ifc-spg``."""
    argv = sys.argv[1:] if argv is None else argv
    p = _parser()
    args, rest = p.parse_known_args(argv)
    if args.verb is None:
        p.print_help()
        return 2
    if args.verb in _PENDING:
        print(f'ifc-spg {args.verb}: pending: {_PENDING[args.verb]}', file=sys.stderr)
        return 2
    print(f'ifc-spg {args.verb}: not implemented yet', file=sys.stderr)
    return 2


if __name__ == '__main__':
    sys.exit(main())
