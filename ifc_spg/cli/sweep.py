"""``ifc-spg sweep FILE -o DIR``: run every point of a sweep file, one results table, figures.

    ifc-spg sweep config/sweeps/free_push_gains.yaml -o out/gains          # local Dask cluster
    ifc-spg sweep FILE -o DIR --workers 1                                  # serial, in-process
    ifc-spg sweep FILE -o DIR --scheduler tcp://HOST:8786                  # existing scheduler
    ifc-spg sweep FILE -o DIR --resume                                     # only missing points
    ifc-spg sweep FILE --check                                             # validate, list points

Writes ``DIR/results.csv`` (one row per run: point, key, status, error, seed, sample,
wall_time_s, the axes, the metrics), ``DIR/runs/KEY.json`` (each run's record with its full
metrics), and figures: ``DIR/METRIC.png`` (the metric against each axis) and, for a sweep
with two axes, ``DIR/METRIC_heatmap.png``. Exit status 0 when every run succeeded, 1 when
some failed (their rows say why), 2 on a bad sweep file or usage, 130 when interrupted
(SIGINT or SIGTERM: the finished runs are kept and in the table; ``--resume`` runs the rest).
"""

import argparse
from collections.abc import Sequence
import os
from pathlib import Path
import signal
import sys
import threading
from types import FrameType

from ifc_spg.errors import IfcSpgError
from ifc_spg.offline.sweep import run_sweep
from ifc_spg.offline.sweep_spec import load_sweep
from ifc_spg.tools.sweep import plot_sweep

__all__ = ['main']


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog='ifc-spg sweep', description=__doc__.split('\n')[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('file', help='sweep file (YAML; see ifc_spg.offline.sweep_spec)')
    p.add_argument('-o', '--output', help='output directory')
    p.add_argument('--workers', type=int, default=None,
                   help='1: serial in this process; N: local Dask cluster of N worker '
                        'processes (default: one per core)')
    p.add_argument('--scheduler', metavar='ADDRESS',
                   help='existing Dask scheduler, e.g. tcp://HOST:8786')
    p.add_argument('--resume', action='store_true',
                   help='skip points whose results exist in DIR/runs')
    p.add_argument('--no-figures', action='store_true', help='write the table only')
    p.add_argument('--check', action='store_true',
                   help='validate the file and list its points; run nothing')
    return p


class _Interrupted(BaseException):
    """A stop asked for by SIGINT/SIGTERM; no ``except Exception`` (a failed run) catches it.

    Not KeyboardInterrupt itself: once under load the CLI ended with status -2 (SIGINT)
    after ``main`` had printed its message and returned 130; the cause was not found (CPython
    and libraries treat KeyboardInterrupt specially). A private exception goes only where
    this module sends it.
    """


def _interrupt_on_signals():
    """SIGINT and SIGTERM raise :class:`_Interrupted`: the sweep writes its table, stops Dask.

    Returns the handlers to restore (none outside the main thread).
    """
    if threading.current_thread() is not threading.main_thread():
        return {}

    def interrupt(signum: int, frame: FrameType | None) -> None:
        raise _Interrupted(signal.Signals(signum).name)
    return {s: signal.signal(s, interrupt) for s in (signal.SIGINT, signal.SIGTERM)}


def _check(file, spec):
    points = spec.points()
    print(f"{file}: ok: {len(points)} points, axes {', '.join(a.path for a in spec.axes)}")
    for p in points:
        print(f'  {p.index:4d} {p.key} {p.params}')
    return 0


def _usage_error(opts):
    """The message for a bad option combination, or None."""
    if not opts.output:
        return '-o DIR is required to run (or --check to validate only)'
    if opts.workers is not None and opts.workers < 1:
        return '--workers must be >= 1'
    return None


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ifc-spg sweep``; the exit status."""
    try:
        opts = _parser().parse_args(sys.argv[1:] if argv is None else argv)
    except SystemExit as exc:
        return 0 if exc.code == 0 else 2
    try:
        spec = load_sweep(opts.file)
    except IfcSpgError as exc:
        print(f'ifc-spg sweep: {exc}', file=sys.stderr)
        return 2
    if opts.check:
        return _check(opts.file, spec)
    if _usage_error(opts):
        print(f'ifc-spg sweep: {_usage_error(opts)}', file=sys.stderr)
        return 2
    out_dir = Path(opts.output)
    # Dask's INFO lines (cluster start, workers joining) would bury the progress line; the
    # spawned workers read this too. Set DASK_LOGGING__DISTRIBUTED=info to see them.
    os.environ.setdefault('DASK_LOGGING__DISTRIBUTED', 'warning')
    old = _interrupt_on_signals()
    try:
        summary = run_sweep(spec, out_dir, workers=opts.workers, scheduler=opts.scheduler,
                            resume=opts.resume, stream=sys.stderr)
    except IfcSpgError as exc:
        print(f'ifc-spg sweep: {exc}', file=sys.stderr)
        return 2
    except (_Interrupted, KeyboardInterrupt):
        print(f'\nifc-spg sweep: interrupted; the finished runs are in {out_dir}/runs and '
              f'{out_dir}/results.csv (--resume runs the rest)', file=sys.stderr)
        return 130
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)
    print(f"results: {summary['table']} ({summary['points']} points: {summary['ran']} run, "
          f"{summary['skipped']} resumed, {summary['failed']} failed)")
    if not opts.no_figures:
        for path in plot_sweep(spec, out_dir, spec.points()):
            print(f'figure: {path}')
    return 1 if summary['failed'] else 0


if __name__ == '__main__':
    sys.exit(main())
