"""Scenario evaluation of constrained manipulation.

The command line (parser, output, exit status) around :mod:`ifc_spg.offline.constrained_evaluate`.
"""

import argparse
from collections.abc import Sequence
import json
import sys

from ifc_spg.offline.constrained_evaluate import QUICK_COMPARISON, accrea, comparison, mechanisms

__all__ = ['main']


def main(argv: Sequence[str] | None = None) -> int:
    """Command line entry: print the JSON report; exit 1 if the trend does not hold."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--only', choices=('comparison', 'mechanisms', 'accrea'), default=None)
    ap.add_argument('--quick', action='store_true', help='short runs (smoke test)')
    ap.add_argument('--sma-initial-error', type=float, default=0.0,
                    help='initial error [deg] of the SMA estimator in the comparison')
    args = ap.parse_args(argv)
    report = {}
    if args.only in (None, 'comparison'):
        kw = {'sma_initial_error_deg': args.sma_initial_error}
        if args.quick:
            kw.update(QUICK_COMPARISON)
        report['comparison'] = comparison(**kw)
    if args.only in (None, 'mechanisms'):
        report['mechanisms'] = mechanisms(duration=10.0 if args.quick else 30.0)
    if args.only in (None, 'accrea'):
        report['accrea'] = accrea(duration=10.0 if args.quick else 20.0)
    json.dump(report, sys.stdout, indent=2, default=str)
    sys.stdout.write('\n')
    ok = True
    if 'comparison' in report:
        c = report['comparison']
        ok = all(c[k]['reduction_percent'] > 0 for k in ('fixed_direction', 'sma_estimator'))
    if 'accrea' in report:
        ok = ok and all(m['success'] for m in report['accrea'].values())
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
