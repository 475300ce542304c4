"""Figures from a bag, in the style of the thesis figures (``ifc-spg plot BAG -o DIR``).

The command line (parser, output, exit status) around :mod:`ifc_spg.tools.plot`.
"""

import argparse
from collections.abc import Sequence
from pathlib import Path
import sys

from ifc_spg.errors import IfcSpgError
from ifc_spg.tools.plot import plot_bag

__all__ = ['main']


def main(argv: Sequence[str] | None = None) -> int:
    """``ifc-spg plot BAG -o DIR``."""
    parser = argparse.ArgumentParser(prog='ifc-spg plot', description=__doc__.split('\n')[0])
    parser.add_argument('bag', help='bag directory')
    parser.add_argument('-o', '--output', required=True, help='directory for the PNGs')
    parser.add_argument('--title', default=None)
    opts = parser.parse_args(sys.argv[1:] if argv is None else argv)
    try:
        paths = plot_bag(opts.bag, opts.output, opts.title)
    except IfcSpgError as exc:
        print(f'ifc-spg plot: {exc}', file=sys.stderr)
        return 2
    print(f'{len(paths)} figures in {opts.output} (open {Path(opts.output) / "index.html"})')
    return 0


if __name__ == '__main__':
    sys.exit(main())
