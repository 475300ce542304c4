"""Video of a run: the measured robot of a bag in its MuJoCo scene (``ifc-spg render``).

The command line (parser, output, exit status) around :mod:`ifc_spg.tools.render`.
"""

import argparse
from collections.abc import Sequence
import sys

from ifc_spg.errors import IfcSpgError
from ifc_spg.tools.render import render

__all__ = ['main']


def main(argv: Sequence[str] | None = None) -> int:
    """``ifc-spg render BAG -o FILE``."""
    parser = argparse.ArgumentParser(prog='ifc-spg render', description=__doc__.split('\n')[0])
    parser.add_argument('bag', help='bag directory')
    parser.add_argument('-o', '--output', required=True, help='video file (.mp4, .gif, .webp)')
    parser.add_argument('--fps', type=float, default=25.0, help='frames per second (25)')
    parser.add_argument('--size', default='640x480', help='WIDTHxHEIGHT (640x480)')
    parser.add_argument('--start', type=float, default=0.0, help='begin S seconds in')
    parser.add_argument('--duration', type=float, default=None, help='render S seconds')
    parser.add_argument('--scene', default=None, help="scene (default: the bag's, or free)")
    parser.add_argument('--no-ghost', action='store_true', help='do not draw q_v')
    parser.add_argument('--shadows', action='store_true',
                        help='shadows and reflections (slower on software GL)')
    parser.add_argument('--no-floor', action='store_true',
                        help='no checker floor (10 cm squares) and 10 cm scale bar')
    parser.add_argument('--view', default='140,-20',
                        help='camera AZIMUTH,ELEVATION in degrees (140,-20; -90 elevation: '
                             'from above)')
    parser.add_argument('-q', '--quiet', action='store_true', help='no progress lines')
    opts = parser.parse_args(sys.argv[1:] if argv is None else argv)
    try:
        w, h = (int(x) for x in opts.size.lower().split('x'))
    except ValueError:
        print(f"ifc-spg render: --size must be WIDTHxHEIGHT, got '{opts.size}'", file=sys.stderr)
        return 2
    try:
        view = tuple(float(x) for x in opts.view.split(','))
    except ValueError:
        print(f"ifc-spg render: --view must be AZIMUTH,ELEVATION, got '{opts.view}'",
              file=sys.stderr)
        return 2
    try:
        res = render(opts.bag, opts.output, opts.fps, (w, h), opts.start, opts.duration,
                     opts.scene, not opts.no_ghost, opts.quiet, shadows=opts.shadows,
                     view=view, floor=not opts.no_floor)
    except IfcSpgError as exc:
        print(f'ifc-spg render: {exc}', file=sys.stderr)
        return 2
    print(f"wrote {res['path']}: {res['frames']} frames at {res['fps']:g} fps, "
          f"{res['size'][0]}x{res['size'][1]}, {res['bytes'] / 1e3:.0f} kB in "
          f"{res['seconds']:.1f} s ({res['frames'] / max(res['seconds'], 1e-9):.1f} frames/s)")
    return 0


if __name__ == '__main__':
    sys.exit(main())
