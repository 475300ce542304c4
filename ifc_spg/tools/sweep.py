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
import math
import os
from pathlib import Path
import re
import signal
import sys
import threading

from ifc_spg.errors import IfcSpgError
from ifc_spg.offline.sweep import read_records, rows, run_sweep
from ifc_spg.offline.sweep_spec import load_sweep

__all__ = ['main', 'plot_sweep']


def _parser():
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


def _number(x):
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _safe(name):
    return re.sub(r'[^A-Za-z0-9_.-]+', '_', name)


def _axis_positions(values):
    """The x positions of axis values: the numbers, else category indices (and their labels)."""
    if all(_number(v) for v in values):
        return [float(v) for v in values], None
    labels = sorted({str(v) for v in values})
    return [labels.index(str(v)) for v in values], labels


def plot_sweep(spec, out_dir, points):
    """Write the figures of a sweep's results; the paths written.

    Per numeric metric: ``METRIC.png``, the metric against each axis (one dot per run; for
    grid axes also the mean over the other axes); with two axes, ``METRIC_heatmap.png``
    (grid x grid: the mean per cell; else the runs as dots coloured by the metric).
    """
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    table = [r for r in rows(spec, read_records(out_dir, points)) if r['status'] == 'ok']
    written = []
    for metric in spec.metrics:
        ok = [r for r in table if _number(r[metric])]
        if not ok:
            continue
        y = [float(r[metric]) for r in ok]
        fig, axs = plt.subplots(1, len(spec.axes), figsize=(4.2 * len(spec.axes), 3.4),
                                squeeze=False)
        for ax, axis in zip(axs[0], spec.axes):
            x, labels = _axis_positions([r[axis.path] for r in ok])
            ax.plot(x, y, 'o', alpha=0.6, ms=4)
            if not axis.random:
                means = {}
                for xi, yi in zip(x, y):
                    means.setdefault(xi, []).append(yi)
                xs = sorted(means)
                ax.plot(xs, [sum(means[k]) / len(means[k]) for k in xs], '-', lw=1.5,
                        label='mean')
            if labels:
                ax.set_xticks(range(len(labels)), labels, rotation=30)
            ax.set_xlabel(axis.path)
            ax.set_ylabel(metric)
            ax.grid(alpha=0.3)
        fig.suptitle(f'{spec.name}: {metric} ({len(ok)} runs)')
        fig.tight_layout()
        path = out_dir / f'{_safe(metric)}.png'
        fig.savefig(path, dpi=100)
        plt.close(fig)
        written.append(path)
        if len(spec.axes) == 2:
            written.append(_heatmap(plt, spec, ok, metric, y, out_dir))
    return written


def _heatmap(plt, spec, ok, metric, y, out_dir):
    a, b = spec.axes
    xa, la = _axis_positions([r[a.path] for r in ok])
    xb, lb = _axis_positions([r[b.path] for r in ok])
    fig, ax = plt.subplots(figsize=(5.6, 4.4))
    if not a.random and not b.random:
        ua, ub = sorted(set(xa)), sorted(set(xb))
        cells = [[[] for _ in ua] for _ in ub]
        for i, j, v in zip(xa, xb, y):
            cells[ub.index(j)][ua.index(i)].append(v)
        grid = [[sum(c) / len(c) if c else math.nan for c in row] for row in cells]
        im = ax.imshow(grid, origin='lower', aspect='auto', cmap='viridis')
        ax.set_xticks(range(len(ua)), la or [f'{v:g}' for v in ua], rotation=30)
        ax.set_yticks(range(len(ub)), lb or [f'{v:g}' for v in ub])
        for r, row in enumerate(grid):
            for c, v in enumerate(row):
                if not math.isnan(v):
                    ax.text(c, r, f'{v:.3g}', ha='center', va='center', color='w', fontsize=8)
    else:
        im = ax.scatter(xa, xb, c=y, cmap='viridis', s=30)
    fig.colorbar(im, ax=ax, label=metric)
    ax.set_xlabel(a.path)
    ax.set_ylabel(b.path)
    ax.set_title(f'{spec.name}: {metric}')
    fig.tight_layout()
    path = out_dir / f'{_safe(metric)}_heatmap.png'
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


class _Interrupted(BaseException):
    """A stop asked for by SIGINT/SIGTERM; no ``except Exception`` (a failed run) catches it.

    Not KeyboardInterrupt itself: CPython and libraries treat that one specially (CPython
    ends the process with SIGINT once it saw one escape code run through ``PyRun_*``), and
    once under load the CLI ended with status -2 (SIGINT) after ``main`` had printed its
    message and returned 130. A private exception goes only where this module sends it.
    """


def _interrupt_on_signals():
    """SIGINT and SIGTERM raise :class:`_Interrupted`: the sweep writes its table, stops Dask.

    Returns the handlers to restore (none outside the main thread).
    """
    if threading.current_thread() is not threading.main_thread():
        return {}

    def interrupt(signum, frame):
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


def main(argv=None):
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
