"""The thesis reproduction harness's records and helpers (:mod:`experiments.reproduce`).

An experiment (:class:`Experiment`) is a list of runs (:class:`RunSpec`), a check that turns
the finished runs (:class:`Run`) into numbers and a summary (:class:`Check`) and a figure;
the experiments themselves are in the modules of their thesis chapter
(:mod:`experiments.ch3`, :mod:`experiments.ch4`, :mod:`experiments.ch5`,
:mod:`experiments.report_ch6`). Here also the series and figure helpers they share.
"""

from collections.abc import Callable
import dataclasses
import math

import numpy as np

from ifc_spg.errors import IfcSpgError

__all__ = ['Check', 'Experiment', 'Run', 'RunSpec']

_T_CIRCLE = 2.0  # stack switch of the table scenarios (press -> experiment) [s]


@dataclasses.dataclass(frozen=True)
class RunSpec:
    """One simulation run of an experiment.

    Attributes:
        label: Run name (directory under ``runs/``).
        scenario: Scenario file name in ``config/scenarios``.
        overrides: Scenario keys replaced (see :func:`ifc_spg.offline.runner.load_scenario`).
        duration: Full-run duration [s] (None: the scenario's).
        quick: Duration of the ``--quick`` run [s].
        full_only: Not run with ``--quick``.
    """

    label: str
    scenario: str
    overrides: dict = dataclasses.field(default_factory=dict)
    duration: float | None = None
    quick: float = 4.0
    full_only: bool = False


@dataclasses.dataclass
class Check:
    """An experiment's numbers and one-line summary; the verdict is its claims'.

    Attributes:
        numbers: What the runs measured (the claims of :mod:`experiments.claims` read it).
        summary: One line of the main numbers (no pass rule: the rules are the claims').
        claims: The evaluated claim rows (:func:`experiments.claims.evaluate`).
        passed: All claims hold (set with ``claims``).
    """

    numbers: dict
    summary: str
    claims: list = dataclasses.field(default_factory=list)
    passed: bool | None = None


@dataclasses.dataclass(frozen=True)
class Experiment:
    """A thesis experiment: its runs, its claim, how to check it and how to draw it."""

    name: str
    table: str
    claim: str
    runs: tuple
    check: Callable[..., Check] | None
    figure: Callable[..., None] | None = None
    figure_title: str = ''
    #: An experiment of ours that tests the cause of a failure (not one of the thesis'):
    #: the report counts it apart
    ours: bool = False


# -- series helpers -------------------------------------------------------------------------

class Run:
    """A finished run: its metrics, bag series and per-task time series."""

    def __init__(self, spec, result):
        from ifc_spg.tools.plot import _task_series, load_series

        self.spec = spec
        self.metrics = result.metrics
        self.s = load_series(result.bag)
        self.tasks = _task_series(self.s)
        self._since = {}
        self.robot = None
        self.scenario = None
        self.pushes = []

    def task(self, name, since=None):
        """Task series (t, value, physical, lower, upper) of ``name``.

        With ``since`` [s] only the statuses from then on (a task of the same name in an
        earlier stack may have another dimension).
        """
        if name not in self.tasks:
            raise IfcSpgError(f"run '{self.spec.label}': no task '{name}' in the status "
                              f"(tasks: {', '.join(self.tasks)})")
        if since is None:
            return self.tasks[name]
        key = (name, since)
        if key not in self._since:
            from ifc_spg.tools.plot import BagSeries, _task_series

            sub = BagSeries()
            keep = [i for i, t in enumerate(self.s.t_status) if t >= since - 1e-9]
            sub.t_status = [self.s.t_status[i] for i in keep]
            sub.status = [self.s.status[i] for i in keep]
            self._since[key] = _task_series(sub)[name]
        return self._since[key]

    def after(self, t0, t=None):
        """Mask of the times ``t`` (default: the joint states') from ``t0`` [s] on."""
        t = self.s.t_js if t is None else t
        return t >= t0 - 1e-9

    def tool_positions(self, chain='tool', virtual=False):
        """Frame positions [m] at the measured (or commanded) q per joint-state sample."""
        import pinocchio as pin

        from ifc_spg.model import RobotModel

        if self.robot is None:
            self.robot = RobotModel.from_config(self.metrics['robot'])
        robot = self.robot
        data = robot.create_data()
        fid = robot.frame_id(chain)
        qs = self.s.q_v if virtual else self.s.q
        pos, rot = [], []
        for q in qs:
            pin.framesForwardKinematics(robot.model, data, np.asarray(q))
            pos.append(data.oMf[fid].translation.copy())
            rot.append(data.oMf[fid].rotation.copy())
        return np.array(pos), np.array(rot)

    def static_torque(self, stiffness):
        """tau_s = K (q_v - q) [Nm] per joint-state sample (q_v of the previous command)."""
        n = min(len(self.s.q), len(self.s.q_v))
        q_v = np.vstack([self.s.q[:1], self.s.q_v[:n - 1]])
        return np.asarray(stiffness) * (q_v - self.s.q[:n])

    def contact_force(self):
        """Force the robot exerts on the environment [N] (base frame)."""
        return -self.s.cw[:, :3]


def _rot_angle(R0, R):
    """Rotation angle [rad] between R0 and each R."""
    c = (np.einsum('ij,nij->n', R0, R) - 1.0) / 2.0
    return np.arccos(np.clip(c, -1.0, 1.0))


def _rms(x):
    x = np.asarray(x, dtype=float)
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else float('nan')


def _smooth(x, n):
    if n <= 1 or len(x) < n:
        return np.asarray(x)
    k = np.ones(n) / n
    return np.convolve(x, k, mode='same')


def _band_err(d, comps=None):
    from ifc_spg.offline.runner import band_error

    sl = slice(None) if comps is None else list(comps)
    ev = band_error(d['value'], d['lower'], d['upper'])[:, sl]
    ep = band_error(d['physical'], d['lower'], d['upper'])[:, sl]
    return np.linalg.norm(ev, axis=1), np.linalg.norm(np.nan_to_num(ep), axis=1)


def _fmt(x, unit='', digits=3):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return 'n/a'
    return f'{x:.{digits}g}{(" " + unit) if unit else ""}'


# -- figures --------------------------------------------------------------------------------

def _plt():
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    plt.rcParams.update({'font.size': 8, 'axes.grid': True, 'grid.alpha': 0.3,
                         'axes.spines.top': False, 'axes.spines.right': False,
                         'legend.fontsize': 7, 'legend.frameon': False, 'lines.linewidth': 1.0})
    return plt


def _save(fig, path):
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    import matplotlib.pyplot as plt
    plt.close(fig)


def _task_panel(ax, d, comp, label, scale=1.0, ylabel=''):
    t = d['t']
    ax.plot(t, d['physical'][:, comp] * scale, color='#d62728', label=f'{label} physical')
    ax.plot(t, d['value'][:, comp] * scale, color='#1f77b4', label=f'{label} virtual')
    lo, hi = d['lower'][:, comp] * scale, d['upper'][:, comp] * scale
    ax.plot(t, lo, 'k--', lw=0.8, label='bounds')
    if not np.allclose(lo, hi, equal_nan=True):
        ax.plot(t, hi, 'k--', lw=0.8)
    ax.set_ylabel(ylabel)



def _shade_pushes(ax, r):
    """Shade the time windows of the run's pushes on ``ax``."""
    for a, b in _push_windows(r):
        ax.axvspan(a, b, color='0.9', zorder=0)


def _scenario_doc(name, folder='scenarios'):
    """The YAML document of ``config/<folder>/<name>``, a fresh dict the caller may edit."""
    import yaml

    from ifc_spg.offline.runner import find_config_dir

    return yaml.safe_load((find_config_dir() / folder / name).read_text(encoding='utf8'))


def _push_windows(run):
    return [(p['at'], p['at'] + p['duration']) for p in run.pushes]
