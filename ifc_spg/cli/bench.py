"""``ifc-spg bench``: the benchmarks of a checkout (``benchmarks/bench.py``), not of the wheel.

The benchmarks are no part of the installed package: this verb finds the ``benchmarks/``
folder next to the ``ifc_spg`` package (a source checkout, or an editable install of one)
and runs ``benchmarks.bench``; installed from a wheel, it says where to get them.
"""

import importlib
from pathlib import Path
import sys
from types import ModuleType

__all__ = ['benchmark_module', 'main']

#: The checkout's folder of the benchmarks, if ifc_spg runs from a checkout.
BENCHMARKS = Path(__file__).resolve().parents[2] / 'benchmarks'


def benchmark_module(name: str, verb: str = 'ifc-spg bench') -> ModuleType | None:
    """``benchmarks.NAME`` of the checkout, or None (a message on stderr) without one.

    Args:
        name: The module in ``benchmarks/`` (``bench``, ``dynamics_bench``).
        verb: The command, for the message.
    """
    if not (BENCHMARKS / f'{name}.py').is_file():
        print(f'{verb}: the benchmarks are not installed with the package (no '
              f'{BENCHMARKS}/{name}.py next to it); run it from a source checkout of ifc_spg, '
              f'or there: python -m benchmarks.{name}', file=sys.stderr)
        return None
    root = str(BENCHMARKS.parent)
    if root not in sys.path:
        sys.path.append(root)
    module = importlib.import_module(f'benchmarks.{name}')
    if Path(module.__file__ or '').resolve().parent != BENCHMARKS:
        print(f'{verb}: benchmarks.{name} was found at {module.__file__}, not in '
              f'{BENCHMARKS}', file=sys.stderr)
        return None
    return module


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ifc-spg bench``: ``benchmarks.bench.main``; 2 without a checkout."""
    module = benchmark_module('bench')
    if module is None:
        return 2
    return int(module.main(sys.argv[1:] if argv is None else argv) or 0)


if __name__ == '__main__':
    sys.exit(main())
