"""The ``sim_bridge``: placeholder until its issue lands."""

import sys


def main(argv=None):
    """Print usage; this executable is a placeholder until the MuJoCo bridge issue lands."""
    print('usage: sim_bridge [--ros-args ...]\n(placeholder: lands with the MuJoCo bridge issue)')
    return 0 if '--help' in (argv or sys.argv[1:]) or '-h' in (argv or sys.argv[1:]) else 2


if __name__ == '__main__':
    sys.exit(main())
