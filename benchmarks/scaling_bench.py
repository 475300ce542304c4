"""``ifc-spg bench --scaling``: how the tick's cost grows with DoF, levels and rows per level.

Three axes, each a series of closed-loop runs (plant not timed, GC off, like the other
``ifc-spg bench`` rows; the tick is ``info.tick_time`` of :meth:`SetPointGenerator.step`):

- ``dof``: serial chains of 7, 17 and 34 revolute joints (:func:`chain_robot`) with the
  5-level Table 4.1 stack of the LBR row (:func:`benchmarks.bench.lbr_stack`);
- ``levels``: 1 to 10 levels on the 7-joint chain, the first L tasks of
  :func:`level_tasks` (Cartesian position, orientation and height, and posture tasks of
  1 to 7 rows on the tool and on a frame mid-chain);
- ``rows``: one level of 1, 3, 6 and 12 rows on the 7-joint chain (:class:`RowsTask`, a
  dense linear task tracking a sine per row), then a posture level.

Every stack also has the implicit joint-torque-limit level and the PSPM layer, as the
default SPG. For each axis the exponent k of p50 ~ x^k is the least-squares slope in
log-log; :func:`plot` draws the three curves.
"""

import gc
import math
import os
import sys
import time

import numpy as np
import pinocchio as pin
from plants import JointImpedancePlant

from ifc_spg import RobotModel, SetPointGenerator
from ifc_spg.tasks import CartesianPoseTask, JointPositionTask
from ifc_spg.tasks.bounds import Bound
from ifc_spg.tasks.task import Task

__all__ = ['AXES', 'RowsTask', 'chain_robot', 'fit_exponent', 'format_scaling', 'level_tasks',
           'plot', 'run_scaling']

#: The points of each axis.
AXES = {'dof': (7, 17, 34), 'levels': tuple(range(1, 11)), 'rows': (1, 3, 6, 12)}

#: Length from the first joint to the tool [m] and mass of the moving links [kg] of a chain.
_REACH, _MASS = 1.1, 20.0


def chain_robot(n):
    """A serial chain of ``n`` revolute joints (axes z, y, z, -y, ...), iiwa-like in size.

    Links of equal length ``_REACH / n`` and mass ``_MASS / n``; frames ``tool`` (past the
    last joint) and ``mid`` (on joint ``n // 2``). Home: an arc, the y joints bent by
    1.2 rad in all (the tool off the base axis, no joint near a limit).
    """
    model = pin.Model()
    length, mass = _REACH / n, _MASS / n
    parent = 0
    q_home = np.zeros(n)
    bend = 1.2 / (n // 2)
    for i in range(n):
        axis = pin.JointModelRZ() if i % 2 == 0 else pin.JointModelRY()
        offset = np.array([0.0, 0.0, 0.15 if i == 0 else length])
        parent = model.addJoint(parent, axis, pin.SE3(np.eye(3), offset), f'j{i + 1}')
        inertia = pin.Inertia(mass, np.array([0.0, 0.0, length / 2]),
                              np.diag([mass * length ** 2 / 12 + 1e-4] * 2 + [1e-4]))
        model.appendBodyToJoint(parent, inertia, pin.SE3.Identity())
        if i % 2:
            q_home[i] = bend
    model.lowerPositionLimit = np.full(n, -2.9)
    model.upperPositionLimit = np.full(n, 2.9)
    model.velocityLimit = np.full(n, 1.5)
    model.effortLimit = np.full(n, 150.0)
    tool = pin.Frame('tool', n, pin.SE3(np.eye(3), np.array([0.0, 0.0, length])),
                     pin.FrameType.OP_FRAME)
    model.addFrame(tool)
    mid = pin.Frame('mid', n // 2, pin.SE3(np.eye(3), np.array([0.0, 0.0, length])),
                    pin.FrameType.OP_FRAME)
    model.addFrame(mid)
    return RobotModel(model, name=f'chain{n}', frames={'tool': 'tool', 'mid': 'mid'},
                      stiffness=200.0, damping=20.0, a_max=8.7, q_home=q_home)


class _Sines(Bound):
    """``amplitude * sin(2 pi freq t + phase_i)`` per row, around the activation value."""

    def __init__(self, dim, amplitude=0.05, freq=0.2):
        self.dim = dim
        self._phase = np.linspace(0.0, np.pi, dim, endpoint=False)
        self._amplitude, self._w = amplitude, 2 * np.pi * freq
        self._center = np.zeros(dim)

    def activate(self, init):
        out = _Sines(self.dim, self._amplitude, self._w / (2 * np.pi))
        out._center = np.array(init, dtype=float)
        return out

    def evaluate(self, t):
        arg = self._w * t + self._phase
        return (self._center + self._amplitude * np.sin(arg),
                self._amplitude * self._w * np.cos(arg))


class RowsTask(Task):
    """A level of ``rows`` dense rows: alpha = M q_v, M fixed (seeded), each row on a sine.

    The rows' count alone changes the cascade's problem; the task's own arithmetic is one
    small matrix-vector product.
    """

    kind = 'rows'
    has_gamma = False

    def __init__(self, robot, rows, seed=0, **kwargs):
        super().__init__(robot, dim=rows, equal=_Sines(rows), **kwargs)
        M = np.random.default_rng(seed).normal(size=(rows, robot.n))
        self._M = M / np.linalg.norm(M, axis=1, keepdims=True)
        self._M.setflags(write=False)

    def compute_value(self, kin):
        """The task value M q_v."""
        return self._M @ kin.q_v

    def compute_jacobian(self, kin):
        """A = M (read-only)."""
        return self._M


def level_tasks(robot, levels):
    """The first ``levels`` (1-10) tasks of a 10-level stack on a chain robot."""
    home = robot.q_home
    data = robot.create_data()
    pin.framesForwardKinematics(robot.model, data, home)
    tool_z = data.oMf[robot.frame_id('tool')].translation[2]
    joints = robot.joint_names
    tasks = [
        CartesianPoseTask(robot, frame='tool', axes=['x', 'y', 'z'], equal=_Sines(3, 0.03),
                          gain=10.0, name='tool_position'),
        CartesianPoseTask(robot, frame='tool', axes=['rx', 'ry', 'rz'], equal='init', gain=10.0,
                          name='tool_orientation'),
        CartesianPoseTask(robot, frame='tool', axes=['z'], lower=[tool_z - 0.05], gain=20.0,
                          name='tool_height'),
        CartesianPoseTask(robot, frame='mid', axes=['x', 'y', 'z'], equal='init', gain=5.0,
                          name='mid_position'),
        CartesianPoseTask(robot, frame='mid', axes=['rx', 'ry', 'rz'], equal='init', gain=5.0,
                          name='mid_orientation'),
        JointPositionTask(robot, joints=joints[:3], equal='init', gain=1.0, name='base_posture'),
        JointPositionTask(robot, joints=joints[3:], equal='init', gain=1.0,
                          name='wrist_posture'),
        CartesianPoseTask(robot, frame='mid', axes=['z'], upper=[1.5], gain=20.0,
                          name='mid_height'),
        CartesianPoseTask(robot, frame='tool', axes=['x', 'y'], equal='init', gain=1.0,
                          name='tool_xy'),
        JointPositionTask(robot, equal=home, gain=1.0, name='posture'),
    ]
    return tasks[:levels]


def _stack(axis, x, robots):
    """(robot, tasks) of point ``x`` of ``axis``."""
    from benchmarks.bench import lbr_stack

    if axis == 'dof':
        robot = robots[x]
        return robot, lbr_stack(robot)
    robot = robots[7]
    if axis == 'levels':
        return robot, level_tasks(robot, x)
    return robot, [RowsTask(robot, x, gain=5.0, name=f'rows_{x}'),
                   JointPositionTask(robot, equal=robot.q_home, gain=1.0, name='posture')]


def _run(spg, robot, ticks):
    """Tick times [s] of ``ticks`` closed-loop ticks and the status counts."""
    plant = JointImpedancePlant(robot, robot.q_home, substeps=1)
    q, qd, t = plant.q, plant.qdot, 0.0
    times = np.empty(ticks)
    statuses = {}
    for i in range(ticks):
        q_v = spg.step(q, qd, t)
        times[i] = spg.info.tick_time
        statuses[spg.info.status] = statuses.get(spg.info.status, 0) + 1
        q, qd, t = plant.step(q_v)
    return times, statuses


def fit_exponent(xs, p50s):
    """The least-squares slope k of log p50 = k log x + c (NaN with fewer than 2 points)."""
    x, y = np.asarray(xs, dtype=float), np.asarray(p50s, dtype=float)
    ok = (x > 0) & (y > 0) & np.isfinite(y)
    if np.count_nonzero(ok) < 2:
        return float('nan')
    return float(np.polyfit(np.log(x[ok]), np.log(y[ok]), 1)[0])


def run_scaling(ticks=2000, warmup=200, progress=True):
    """Run the three axes; return a JSON-friendly dict (points per axis and exponents)."""
    from benchmarks.bench import _stats

    robots = {n: chain_robot(n) for n in AXES['dof']}
    out = {'ticks': ticks, 'warmup': warmup, 'axes': {}, 'exponents': {},
           'load_average': os.getloadavg()[0]}
    t_start = time.perf_counter()
    for axis, xs in AXES.items():
        rows = []
        for x in xs:
            robot, tasks = _stack(axis, x, robots)
            spg = SetPointGenerator(robot, tasks)
            _run(spg, robot, warmup)
            gc.collect()
            gc.disable()
            try:
                times, statuses = _run(spg, robot, ticks)
            finally:
                gc.enable()
            row = {'x': x, 'dof': robot.n, 'levels': len(tasks),
                   'rows': [t.dim for t in tasks], **_stats(times), 'status': statuses}
            rows.append(row)
            if progress:
                print(f'  {axis:<7}{x:>3}: p50 {row["p50_us"]:7.1f} us  p99 '
                      f'{row["p99_us"]:7.1f} us  {statuses}', file=sys.stderr)
        out['axes'][axis] = rows
        out['exponents'][axis] = fit_exponent(xs, [r['p50_us'] for r in rows])
    out['seconds'] = time.perf_counter() - t_start
    return out


_LABELS = {'dof': 'DoF (chain, 5-level Table 4.1 stack)',
           'levels': 'levels (7-DoF chain)',
           'rows': 'rows in one level (7-DoF chain, + posture level)'}


def format_scaling(res):
    """The table and the exponents as text."""
    lines = [f"Tick cost scaling, closed loop, {res['ticks']} ticks per point (GC off, plant "
             f"not timed; load average {res['load_average']:.1f} at the start); exponent k of "
             'p50 ~ x^k (log-log least squares):']
    for axis, rows in res['axes'].items():
        lines.append(f"  {_LABELS[axis]}: k = {res['exponents'][axis]:.2f}")
        lines.append('    ' + '  '.join(f"{r['x']:>3}: {r['p50_us']:5.0f}/{r['p99_us']:.0f}"
                                         for r in rows) + '  (p50/p99 us)')
    return '\n'.join(lines)


def plot(res, path):
    """The three curves (p50 with p99 dashed, log-log) in one PNG at ``path``."""
    import matplotlib  # heavy, and only for the figure
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6), sharey=True)
    for ax, (axis, rows) in zip(axes, res['axes'].items(), strict=True):
        x = [r['x'] for r in rows]
        ax.loglog(x, [r['p50_us'] for r in rows], 'o-', label='p50')
        ax.loglog(x, [r['p99_us'] for r in rows], 's--', label='p99', alpha=0.7)
        k = res['exponents'][axis]
        ax.set_title(f'k = {k:.2f}' if math.isfinite(k) else 'k = n/a', fontsize=10)
        ax.set_xlabel(_LABELS[axis], fontsize=9)
        ax.set_xticks(x)
        ax.set_xticklabels([str(v) for v in x], fontsize=8)
        ax.minorticks_off()
        ax.grid(True, which='major', alpha=0.3)
    axes[0].set_ylabel('tick [us]')
    axes[0].legend(fontsize=8)
    fig.suptitle(f"SPG tick cost, closed loop, {res['ticks']} ticks per point (load average "
                 f"{res['load_average']:.1f})", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
