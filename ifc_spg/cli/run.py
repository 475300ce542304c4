"""Offline lockstep runs of a scenario: bridge + SPG in one process, no DDS (``ifc-spg run``).

The command line (parser, output, exit status) around :mod:`ifc_spg.offline.runner`.
"""

import argparse
from collections.abc import Sequence
import json
import sys

from ifc_spg.errors import IfcSpgError
from ifc_spg.offline.runner import StopRequest, run_scenario, stop_request

__all__ = ['main']


def main(argv: Sequence[str] | None = None) -> int:
    """``ifc-spg run SCENARIO.yaml -o DIR``."""
    parser = argparse.ArgumentParser(prog='ifc-spg run', description=__doc__.split('\n')[0])
    parser.add_argument('scenario', help='scenario YAML file (or a name in config/scenarios)')
    parser.add_argument('-o', '--output', required=True, help='output directory')
    parser.add_argument('--duration', type=float, default=None, help='override [s]')
    parser.add_argument('-q', '--quiet', action='store_true', help='no progress output')
    opts = parser.parse_args(sys.argv[1:] if argv is None else argv)
    old = stop_request.install()
    try:
        result = run_scenario(opts.scenario, opts.output, opts.duration, opts.quiet)
    except IfcSpgError as exc:
        print(f'ifc-spg run: {exc}', file=sys.stderr)
        return 2
    finally:
        StopRequest.restore(old)
    print(f'bag: {result.bag}\nmetrics: {result.metrics_path}')
    print(json.dumps({k: v for k, v in result.metrics.items() if k not in ('spg',)}, indent=1))
    return 130 if stop_request.requested else 0


if __name__ == '__main__':
    sys.exit(main())
