"""Figures from a bag, in the style of the thesis figures (``ifc-spg plot BAG -o DIR``).

One PNG per concept, plus ``index.html`` listing them (and ``metrics.json`` when it sits
next to the bag):

- ``task_<name>.png`` per task of the stacks: each subspace component's virtual value
  (at q_v), physical value (at the measured q; for wrench tasks the measured contact
  force) and its bounds (desired value of an equality task, the band of an inequality);
  from the ``tasks`` entries of ``spg/status``.
- ``joints.png``: measured q vs commanded q_v per joint [deg].
- ``contact_force.png``: force the robot exerts on the environment [N] (``sim/contact_wrench``
  negated; F/T sensors too when recorded).
- ``torques.png``: measured joint torques [Nm] (``joint_states`` effort).
- ``tanks.png``: PSPM tank energies per joint [J].
- ``timing.png``: SPG tick and solve time [ms] over time and their distribution.

Vertical dotted lines mark task-stack switches. Rendering uses matplotlib's Agg backend
(no display needed).
"""

import html
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from ifc_spg.errors import IfcSpgError
from ifc_spg.offline.bag import BagReader, stamp_ns

__all__ = ['BagSeries', 'load_series', 'plot_bag']

_COLORS = ('#1f77b4', '#d62728', '#2ca02c', '#9467bd', '#ff7f0e', '#8c564b', '#e377c2',
           '#7f7f7f', '#bcbd22', '#17becf')


class BagSeries:
    """Time series of a bag, as numpy arrays (time in [s] from the first stamp)."""

    def __init__(self):
        self.joint_names = []
        self.t_js, self.q, self.qd, self.effort = [], [], [], []
        self.t_cmd, self.q_v = [], []
        self.t_cw, self.cw = [], []
        self.ft = {}
        self.t_status, self.status = [], []
        self.t_stacks, self.stack_names = [], []
        self.t0 = None

    def add(self, name, msg):
        """Append one message of topic ``name`` (relative); other topics are ignored."""
        if name == 'joint_states':
            self.joint_names = list(msg.name)
            self.t_js.append(stamp_ns(msg.header.stamp))
            self.q.append(list(msg.position))
            self.qd.append(list(msg.velocity))
            self.effort.append(list(msg.effort))
        elif name == 'command/joint_position':
            self.t_cmd.append(stamp_ns(msg.header.stamp))
            self.q_v.append(list(msg.position))
        elif name == 'sim/contact_wrench':
            self.t_cw.append(stamp_ns(msg.header.stamp))
            self.cw.append(_wrench(msg))
        elif name == 'ft_sensor/wrench':
            t, w = self.ft.setdefault(msg.header.frame_id, ([], []))
            t.append(stamp_ns(msg.header.stamp))
            w.append(_wrench(msg))
        elif name == 'spg/status':
            try:
                doc = json.loads(msg.data)
            except json.JSONDecodeError:
                return
            self._add_status(doc)

    def _add_status(self, doc):
        if doc.get('stamp') is None:
            return
        self.t_status.append(round(float(doc['stamp']) * 1e9))
        self.status.append(doc)
        st = doc.get('stack') or {}
        if st.get('name') and (not self.stack_names or self.stack_names[-1] != st['name']):
            since = st.get('since', doc['stamp'])
            self.t_stacks.append(round(float(since) * 1e9))
            self.stack_names.append(st['name'])

    def finish(self):
        """Turn the lists into arrays, times in [s] from the first stamp."""
        stamps = [x[0] for x in (self.t_js, self.t_cmd, self.t_cw, self.t_status) if x]
        self.t0 = min(stamps) if stamps else 0
        for attr in ('t_js', 't_cmd', 't_cw', 't_status', 't_stacks'):
            setattr(self, attr, (np.array(getattr(self, attr), dtype=np.int64) - self.t0) * 1e-9)
        for attr in ('q', 'qd', 'effort', 'q_v', 'cw'):
            setattr(self, attr, np.array(getattr(self, attr), dtype=float))
        self.ft = {k: ((np.array(t, dtype=np.int64) - self.t0) * 1e-9, np.array(w))
                   for k, (t, w) in self.ft.items()}


def load_series(path):
    """Read a bag into a :class:`BagSeries`."""
    s = BagSeries()
    with BagReader(path) as bag:
        for topic, _t_log, msg in bag.messages():
            s.add(topic.lstrip('/'), msg)
    s.finish()
    return s


def _wrench(msg):
    f, t = msg.wrench.force, msg.wrench.torque
    return [f.x, f.y, f.z, t.x, t.y, t.z]


def _style(plt):
    plt.rcParams.update({'font.size': 9, 'axes.grid': True, 'grid.alpha': 0.3,
                         'axes.spines.top': False, 'axes.spines.right': False,
                         'legend.fontsize': 8, 'legend.frameon': False,
                         'figure.dpi': 100, 'savefig.dpi': 110})


def _switches(ax, s):
    for t in s.t_stacks[1:]:
        ax.axvline(t, color='0.4', lw=0.8, ls=':')


def _grid(n):
    cols = 1 if n <= 3 else 2 if n <= 8 else 3
    rows = int(np.ceil(n / cols))
    return rows, cols


def _task_series(s):
    """Task name -> dict(t, value, physical, lower, upper, type) from the statuses."""
    out: dict[str, dict[str, Any]] = {}
    for t, doc in zip(s.t_status, s.status):
        for task in doc.get('tasks') or []:
            d = out.setdefault(task['name'], {'t': [], 'value': [], 'physical': [], 'lower': [],
                                              'upper': [], 'type': task.get('type', '')})
            m = len(task['value'])
            if d['value'] and len(d['value'][-1]) != m:
                continue  # same name, different dimension in another stack: keep the first
            d['t'].append(t)
            d['value'].append(task['value'])
            nan = [np.nan] * m
            d['physical'].append(task['physical'] if task.get('physical') is not None else nan)
            d['lower'].append([np.nan if x is None else x for x in task['lower']])
            d['upper'].append([np.nan if x is None else x for x in task['upper']])
    for d in out.values():
        for k in ('t', 'value', 'physical', 'lower', 'upper'):
            d[k] = np.array(d[k], dtype=float)
    return out


_UNITS = {'wrench': ('N', 1.0), 'joint_torque': ('Nm', 1.0), 'cartesian_pose': ('m | rad', 1.0),
          'joint_position': ('deg', 180.0 / np.pi)}


def _plot_task(plt, s, name, d, path):
    m = d['value'].shape[1]
    rows, cols = _grid(m)
    fig, axes = plt.subplots(rows, cols, figsize=(7.5 if cols > 1 else 6.5, 1.9 * rows + 0.6),
                             sharex=True, squeeze=False)
    unit, scale = _UNITS.get(d['type'], ('', 1.0))
    for k in range(rows * cols):
        ax = axes[k // cols][k % cols]
        if k >= m:
            ax.set_visible(False)
            continue
        t = d['t']
        lo, hi = d['lower'][:, k] * scale, d['upper'][:, k] * scale
        equal = np.allclose(lo, hi, equal_nan=True)
        if equal:
            ax.plot(t, lo, color='k', ls='--', lw=1.0, label='desired')
        else:
            finite_lo, finite_hi = np.where(np.isfinite(lo), lo, np.nan), \
                np.where(np.isfinite(hi), hi, np.nan)
            ax.plot(t, finite_lo, color='k', ls='--', lw=0.9, label='bounds')
            ax.plot(t, finite_hi, color='k', ls='--', lw=0.9)
            ax.fill_between(t, np.where(np.isfinite(lo), lo, -1e9),
                            np.where(np.isfinite(hi), hi, 1e9), color='0.85', alpha=0.5, lw=0,
                            where=np.isfinite(lo) & np.isfinite(hi))
        ax.plot(t, d['value'][:, k] * scale, color=_COLORS[0], lw=1.2, label='virtual (q_v)')
        if np.any(np.isfinite(d['physical'][:, k])):
            ax.plot(t, d['physical'][:, k] * scale, color=_COLORS[1], lw=1.0, alpha=0.85,
                    label='physical (q)')
        _fit_ylim(ax, [d['value'][:, k] * scale, d['physical'][:, k] * scale, lo, hi])
        _switches(ax, s)
        ax.set_ylabel(f'[{k}] [{unit}]' if unit else f'[{k}]')
        if k == 0:
            ax.legend(loc='best', ncol=2)
    for ax in axes[-1]:
        ax.set_xlabel('time [s]')
    fig.suptitle(f"task '{name}' ({d['type']})")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _fit_ylim(ax, arrays):
    vals = np.concatenate([np.asarray(a, float)[np.isfinite(a)] for a in arrays])
    if vals.size:
        lo, hi = vals.min(), vals.max()
        pad = 0.08 * (hi - lo) if hi > lo else max(abs(hi) * 0.1, 1e-3)
        ax.set_ylim(lo - pad, hi + pad)


def _per_joint(plt, s, t_a, a, t_b, b, labels, ylabel, title, path, scale=1.0):
    n = a.shape[1]
    rows, cols = _grid(n)
    fig, axes = plt.subplots(rows, cols, figsize=(7.5 if cols > 1 else 6.5, 1.7 * rows + 0.6),
                             sharex=True, squeeze=False)
    for j in range(rows * cols):
        ax = axes[j // cols][j % cols]
        if j >= n:
            ax.set_visible(False)
            continue
        ax.plot(t_a, a[:, j] * scale, color=_COLORS[0], lw=1.2, label=labels[0])
        if b is not None and b.size:
            ax.plot(t_b, b[:, j] * scale, color=_COLORS[1], lw=1.0, ls='--', label=labels[1])
        _switches(ax, s)
        name = s.joint_names[j] if j < len(s.joint_names) else str(j)
        ax.set_ylabel(f'{name} [{ylabel}]')
        if j == 0 and labels[1]:
            ax.legend(loc='best', ncol=2)
    for ax in axes[-1]:
        ax.set_xlabel('time [s]')
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_bag(bag, out_dir, title=None, video=None):
    """Write the figures and ``index.html`` into ``out_dir``; returns the PNG paths.

    Args:
        bag: Bag directory.
        out_dir: Directory for the PNGs and ``index.html`` (created).
        title: Page title (default: names the bag).
        video: A video file of the run (``ifc-spg render``) shown above the figures.

    Raises:
        IfcSpgError: The bag has no joint states.
    """
    import matplotlib  # heavy, and only for figures
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    _style(plt)
    s = load_series(bag)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if not len(s.t_js):
        raise IfcSpgError(f"bag '{bag}' has no joint_states messages to plot")
    written = _task_figures(plt, s, out)
    path = out / 'joints.png'
    _per_joint(plt, s, s.t_js, s.q, s.t_cmd, s.q_v if s.q_v.size else None,
               ('measured q', 'commanded q_v'), 'deg', 'joint positions', path, 180 / np.pi)
    written.append((path, 'joint positions q vs q_v'))
    if len(s.t_cw) or s.ft:
        written.append(_contact_figure(plt, s, out / 'contact_force.png'))
    if s.effort.size:
        path = out / 'torques.png'
        _per_joint(plt, s, s.t_js, s.effort, None, None, ('measured torque', None), 'Nm',
                   'joint torques', path)
        written.append((path, 'joint torques'))
    tanks = [(t, d['tank_energy']) for t, d in zip(s.t_status, s.status)
             if d.get('tank_energy')]
    if tanks:
        written.append(_tanks_figure(plt, s, tanks, out / 'tanks.png'))
    timing = [(t, d.get('tick_time'), d.get('solve_time')) for t, d in
              zip(s.t_status, s.status) if d.get('tick_time') is not None]
    if timing:
        written.append(_timing_figure(plt, s, timing, out / 'timing.png'))
    _index(out, written, Path(bag), title, video)
    return [p for p, _ in written]


def _task_figures(plt, s, out):
    """``task_<name>.png`` per task with values; ``[(path, caption)]``."""
    written = []
    for name, d in _task_series(s).items():
        if d['value'].size:
            safe = ''.join(c if c.isalnum() or c in '-_' else '_' for c in name)
            path = out / f'task_{safe}.png'
            _plot_task(plt, s, name, d, path)
            written.append((path, f"task '{name}': value vs bounds"))
    return written


def _save(plt, fig, path, caption):
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path, caption


def _contact_figure(plt, s, path):
    fig, ax = plt.subplots(figsize=(6.5, 3.2))
    if len(s.t_cw):
        f = -s.cw[:, :3]
        for k, axis in enumerate('xyz'):
            ax.plot(s.t_cw, f[:, k], color=_COLORS[k], lw=1.0, label=f'f{axis}')
        ax.plot(s.t_cw, np.linalg.norm(f, axis=1), color='k', lw=1.2, label='|f|')
    for chain, (t, w) in s.ft.items():
        ax.plot(t, np.linalg.norm(w[:, :3], axis=1), lw=1.0, ls='--', label=f'|f| F/T {chain}')
    _switches(ax, s)
    ax.set_xlabel('time [s]')
    ax.set_ylabel('force on environment [N]')
    ax.set_title('contact force (robot on environment)')
    ax.legend(loc='best', ncol=5)
    return _save(plt, fig, path, 'contact force')


def _tanks_figure(plt, s, tanks, path):
    t = np.array([x[0] for x in tanks])
    e = np.array([x[1] for x in tanks], dtype=float)
    fig, ax = plt.subplots(figsize=(6.5, 3.2))
    for j in range(e.shape[1]):
        name = s.joint_names[j] if j < len(s.joint_names) else str(j)
        ax.plot(t, e[:, j], color=_COLORS[j % len(_COLORS)], lw=1.0, label=name)
    _switches(ax, s)
    ax.set_xlabel('time [s]')
    ax.set_ylabel('tank energy [J]')
    ax.set_title('PSPM energy tanks')
    ax.set_ylim(bottom=0)
    ax.legend(loc='best', ncol=4)
    return _save(plt, fig, path, 'PSPM tank energies')


def _timing_figure(plt, s, timing, path):
    t = np.array([x[0] for x in timing])
    tick = np.array([x[1] for x in timing], dtype=float) * 1e3
    solve = np.array([x[2] or 0.0 for x in timing], dtype=float) * 1e3
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(8, 3.0), gridspec_kw={'width_ratios': [2, 1]})
    a1.plot(t, tick, color=_COLORS[0], lw=0.8, label='tick')
    a1.plot(t, solve, color=_COLORS[2], lw=0.8, label='solve')
    _switches(a1, s)
    a1.set_xlabel('time [s]')
    a1.set_ylabel('[ms]')
    a1.legend(loc='best')
    p50, p99 = np.percentile(tick, [50, 99])
    a2.hist(tick, bins=40, color=_COLORS[0], alpha=0.8)
    a2.axvline(p50, color='k', ls='--', lw=0.8)
    a2.axvline(p99, color=_COLORS[1], ls='--', lw=0.8)
    a2.set_xlabel(f'tick [ms]  (p50 {p50:.2f}, p99 {p99:.2f})')
    a2.set_ylabel('count')
    fig.suptitle('SPG timing')
    return _save(plt, fig, path, 'SPG tick and solve time')


def _video_html(out, video):
    if video is None:
        return ''
    video = Path(video)
    try:
        src = Path(os.path.relpath(video.resolve(), out.resolve())).as_posix()
    except ValueError:  # another drive (Windows)
        src = video.resolve().as_uri()
    src = html.escape(src)
    if video.suffix.lower() == '.mp4':
        return (f'<h2>the run</h2><video src="{src}" controls loop muted autoplay '
                'style="max-width:100%"></video>')
    return f'<h2>the run</h2><img src="{src}" alt="video of the run">'


def _index(out, written, bag, title, video=None):
    metrics = bag.parent / 'metrics.json'
    rows = ''
    if metrics.is_file():
        rows = '<h2>metrics</h2><pre>' + html.escape(metrics.read_text(), quote=False) + '</pre>'
    items = '\n'.join(f'<h3>{html.escape(text)}</h3><img src="{p.name}" alt="{html.escape(text)}">'
                      for p, text in written)
    title = html.escape(title or f'ifc_spg run: {bag}')
    links = ''.join(f'<li><a href="{p.name}">{p.name}</a></li>' for p, _ in written)
    (out / 'index.html').write_text(
        f'<!doctype html><html><head><meta charset="utf-8"><title>{title}</title>'
        '<style>body{font-family:sans-serif;max-width:900px;margin:auto}img{max-width:100%}'
        f'</style></head><body><h1>{title}</h1><p>bag: <code>{html.escape(str(bag))}</code></p>'
        f'{_video_html(out, video)}<ul>{links}</ul>{items}{rows}</body></html>\n',
        encoding='utf8')
