"""Recompute the SPG output from a bag and compare it with the recorded commands.

The command line (parser, output, exit status) around :mod:`ifc_spg.offline.replay`.
"""

import argparse
from collections.abc import Sequence
import dataclasses
import json
import sys

from ifc_spg.errors import IfcSpgError
from ifc_spg.offline.replay import replay

__all__ = ['main']


def main(argv: Sequence[str] | None = None) -> int:
    """``ifc-spg replay BAG``."""
    parser = argparse.ArgumentParser(prog='ifc-spg replay', description=__doc__.split('\n')[0])
    parser.add_argument('bag', help='bag directory')
    parser.add_argument('--tolerance', type=float, default=1e-9,
                        help='max |dq_v| [rad] accepted (default 1e-9)')
    parser.add_argument('--robot', default=None, help='robot, if the bag does not say')
    parser.add_argument('--json', action='store_true', help='print the result as JSON')
    opts = parser.parse_args(sys.argv[1:] if argv is None else argv)
    try:
        res = replay(opts.bag, opts.robot)
    except IfcSpgError as exc:
        print(f'ifc-spg replay: {exc}', file=sys.stderr)
        return 2
    for warning in res.warnings:
        print(f'ifc-spg replay: warning: {warning}', file=sys.stderr)
    ok = res.compared > 0 and res.missing == 0 and res.max_abs_diff <= opts.tolerance
    if opts.json:
        print(json.dumps({**dataclasses.asdict(res), 'tolerance': opts.tolerance, 'ok': ok}))
    else:
        gains = 'K, D from the bag' if res.gains_recorded else 'default K, D'
        edges = ''
        if res.resumed:
            edges += (f'; from the first recorded spg/state ({res.skipped} earlier joint '
                      'state(s) not replayed)')
        if res.not_ticked:
            edges += (f'; {res.not_ticked} joint state(s) the live SPG did not tick on '
                      '(spg/state shows it; not replayed)')
        if res.unanswered:
            edges += (f'; {res.unanswered} joint state(s) after the last recorded command '
                      '(recording ended)')
        if res.lost:
            edges += (f'; the bag lacks {res.lost} tick(s) the live SPG ran (the recorder '
                      f'missed them): {res.resyncs} resynchronisation(s) from spg/state, '
                      f'{res.unverified} command(s) not compared')
        print(f'replayed {res.ticks} ticks ({res.stacks} task stack(s), robot '
              f"'{res.config['robot']}' with {gains}, solver {res.config['solver']}); compared "
              f'{res.compared} commands, {res.missing} missing{edges}')
        where = '' if res.worst_stamp is None else \
            f' (t = {res.worst_stamp:.3f} s, joint {res.worst_joint})'
        print(f'max |dq_v| = {res.max_abs_diff:.3e} rad{where}; tolerance {opts.tolerance:g}: '
              + ('OK' if ok else 'FAILED'))
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
