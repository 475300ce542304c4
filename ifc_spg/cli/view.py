"""``ifc-spg view BAG``: a browser cockpit of a recorded run (viser).

The command line (parser, output, exit status) around :mod:`ifc_spg.tools.view`.
"""

import argparse
from collections.abc import Sequence
import sys
import time

from ifc_spg.errors import IfcSpgError
from ifc_spg.tools.view import Cockpit, LiveCockpit, load_bag

__all__ = ['main']


def main(argv: Sequence[str] | None = None) -> int:
    """``ifc-spg view BAG``."""
    parser = argparse.ArgumentParser(prog='ifc-spg view', description=__doc__.split('\n')[0])
    parser.add_argument('bag', nargs='?', help='bag directory (ifc-spg run / bag record)')
    parser.add_argument('--live', metavar='ROBOT', default=None,
                        help='instead of a bag: the running SPG of robot ROBOT, from its '
                             'topics (drag a gizmo to stream a target; enable and the live '
                             'parameters of its spg_node in the page)')
    parser.add_argument('--spg-node', default='spg_node',
                        help='with --live: the SPG node whose enable and live parameters the '
                             'page sets (default spg_node)')
    parser.add_argument('--host', default='127.0.0.1',
                        help='interface to serve on (default loopback; 0.0.0.0 exposes it)')
    parser.add_argument('--port', type=int, default=8080, help='TCP port (default 8080)')
    opts = parser.parse_args(sys.argv[1:] if argv is None else argv)
    if (opts.bag is None) == (opts.live is None):
        parser.error('give a bag directory or --live ROBOT')
    try:
        cockpit = LiveCockpit(opts.live, None, opts.host, opts.port,
                              opts.spg_node) if opts.live else \
            Cockpit(load_bag(opts.bag), opts.host, opts.port)
    except IfcSpgError as exc:
        print(f'ifc-spg view: {exc}', file=sys.stderr)
        return 2
    except OSError as exc:
        print(f'ifc-spg view: cannot serve on {opts.host}:{opts.port}: {exc}', file=sys.stderr)
        return 2
    print(f'ifc-spg view: {cockpit.url} (Ctrl-C to stop)', flush=True)
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        pass
    finally:
        cockpit.close()
    return 0


if __name__ == '__main__':
    sys.exit(main())
