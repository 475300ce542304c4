"""Generate the shared MJCF model files of the KUKA arms and the dual-arm robot.

The command line (parser, output, exit status) around :mod:`ifc_spg.model.generate`.
"""

import argparse
import os
import sys

from ifc_spg.model.generate import generate
from ifc_spg.model.registry import DATA_DIR

__all__ = ['main']


def main(argv: list[str] | None = None) -> int:
    """Write (or with ``--check`` verify) the generated files in ``ifc_spg/model/data``."""
    parser = argparse.ArgumentParser(prog='python -m ifc_spg.cli.generate',
                                     description=__doc__.splitlines()[0])
    parser.add_argument('--check', action='store_true',
                        help='do not write; exit 1 if a committed file differs')
    parser.add_argument('--out', default=DATA_DIR, help='output directory (default: %(default)s)')
    args = parser.parse_args(argv)
    stale = []
    for fname, text in generate().items():
        path = os.path.join(args.out, fname)
        if args.check:
            try:
                with open(path, encoding='utf-8') as f:
                    same = f.read() == text
            except FileNotFoundError:
                same = False
            if not same:
                stale.append(path)
            continue
        os.makedirs(args.out, exist_ok=True)
        with open(path, 'w', encoding='utf-8') as f:
            f.write(text)
        print(f'wrote {path}')
    if stale:
        print('stale generated model files (run python -m ifc_spg.cli.generate): '
              + ', '.join(stale), file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
