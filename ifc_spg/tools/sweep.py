"""Figures of a sweep's results (``ifc-spg sweep`` draws them after the runs).

:func:`plot_sweep` writes ``DIR/METRIC.png`` (the metric against each axis) and, for a sweep
with two axes, ``DIR/METRIC_heatmap.png``, from the records in ``DIR/runs``.
"""

import math
import re

from ifc_spg.offline.sweep import read_records, rows

__all__ = ['plot_sweep']


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
                means: dict[float, list[float]] = {}
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
        cells: list[list[list[float]]] = [[[] for _ in ua] for _ in ub]
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
