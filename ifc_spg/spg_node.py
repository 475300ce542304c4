"""The ``spg_node``: placeholder until its issue lands."""

import sys


def main(argv=None):
    """Print usage; this executable is a placeholder until the end-to-end issue lands."""
    print('usage: spg_node [--ros-args ...]\n(placeholder: lands with the end-to-end issue)')
    return 0 if '--help' in (argv or sys.argv[1:]) or '-h' in (argv or sys.argv[1:]) else 2


if __name__ == '__main__':
    sys.exit(main())
