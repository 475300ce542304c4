"""The simulated LBR demo (``ifc-spg demo``): surface tracking on a table, bag, metrics, plots.

The command line (parser, output, exit status) around :mod:`ifc_spg.tools.demo`.
"""

import argparse
from collections.abc import Sequence
import sys

from ifc_spg.errors import IfcSpgError
from ifc_spg.tools.demo import run_demo, summary

__all__ = ['main']


def main(argv: Sequence[str] | None = None) -> int:
    """``ifc-spg demo``."""
    parser = argparse.ArgumentParser(prog='ifc-spg demo', description=__doc__.split('\n')[0])
    parser.add_argument('--duration', type=float, default=None,
                        help='simulated seconds (default: the scenario, 20 s)')
    parser.add_argument('-o', '--output', default='out/demo', help='output directory')
    parser.add_argument('--no-plots', action='store_true', help='skip the figures')
    parser.add_argument('--no-video', action='store_true', help='skip the video')
    parser.add_argument('-q', '--quiet', action='store_true', help='no progress lines')
    opts = parser.parse_args(sys.argv[1:] if argv is None else argv)
    try:
        result, pngs = run_demo(opts.output, opts.duration, not opts.no_plots, opts.quiet,
                                not opts.no_video)
    except IfcSpgError as exc:
        print(f'ifc-spg demo: {exc}', file=sys.stderr)
        return 2
    print(summary(result, pngs))
    return 0


if __name__ == '__main__':
    sys.exit(main())
