"""``ifc-spg bench``: the SPG tick time per solver, and our strict stack next to pink.

Full tick = kinematics + task assembly + solve + joint limits + PSPM, measured inside
:meth:`SetPointGenerator.step` (``info.tick_time``) in a closed loop with a simple
joint-impedance plant (the plant is not timed). Stacks:

- ``lbr_table_4_1``: LBR iiwa 14, the 5-level stack of Table 4.1 (variant 1b: obstacle
  as a Cartesian inequality, joint-torque inequality, circle trajectory, orientation,
  posture) plus the implicit torque-limit level;
- ``icub_table_3_7``: iCub upper body, the 7-level stack of Table 3.7 (wiping with the
  left hand while the right hand holds a cup);
- ``native_ratio``: the LBR and iCub stacks with the C kernels of the tick
  (``ifc_spg.kernels._native``) and with their numpy reference code, two closed loops in one
  process, interleaved tick by tick;
- ``daqp_native_ratio``: the same stacks with the level solves called from C
  (``ifc_spg.cascade._daqp_native``) and through DAQP's Python module, likewise, and the
  Python calls per tick of each;
- ``pink_ratio``: a 2-level strict stack (pose, posture) on the iiwa, next to pink's
  weighted solve of the same two tasks (``pink.solve_ik`` with DAQP), same process,
  interleaved tick by tick so that machine load affects both alike;
- ``collision``: the tick with and without a ``collision_avoidance`` level (iiwa: 47
  pairs, ACCREA: 218 self pairs) and the level's rows next to mink's
  ``CollisionAvoidanceLimit`` on the same pairs (:mod:`benchmarks.collision_bench`).

``--scaling`` runs the cost curve instead (:mod:`benchmarks.scaling_bench`): tick p50/p99
against DoF, levels and rows per level, with the fitted exponents and a figure.

Targets (issue 3): LBR p99 <= 0.3 ms and max <= 1 ms; iCub p99 <= 0.6 ms; ratio <= 1.0.

A machine baseline runs next to each DAQP row, tick by tick: a fixed piece of pure Python
work of about the same length, timed the same way. Its max and its count of periods over
1 ms tell the machine's own scheduling stalls apart from the SPG's.
"""

import argparse
import gc
import json
from pathlib import Path
import subprocess
import sys
import time

import numpy as np
import pinocchio as pin
from plants import JointImpedancePlant

from ifc_spg import RobotModel, SetPointGenerator, TaskStack, kernels
from ifc_spg.cascade import daqp as daqp_cascade
from ifc_spg.offline.runner import find_config_dir
from ifc_spg.task_stack.trajectories import Anchor, Circle
from ifc_spg.tasks import CartesianPoseTask, JointPositionTask, JointTorqueTask, WrenchTask

__all__ = ['main', 'run_benchmarks']


def _circle(center, radius, freq, plane=(1, 2), select=(0, 1, 2)):
    """A circle in ``plane`` around ``center`` (3D) on the task components ``select``.

    The library's generator, which a YAML stack's ``{trajectory: circle}`` builds.
    """
    select = list(select)
    return Circle(len(select), plane=(select.index(plane[0]), select.index(plane[1])),
                  radius=radius, frequency=freq,
                  center=Anchor(np.asarray(center, dtype=float)[list(plane)]))


def _tool_pose(robot, q, frame):
    data = robot.create_data()
    pin.framesForwardKinematics(robot.model, data, q)
    return data.oMf[robot.frame_id(frame)].translation.copy()


def lbr_stack(robot):
    """Table 4.1 (1b) on the iiwa: 5 levels."""
    p0 = _tool_pose(robot, robot.q_home, 'tool')
    return [
        CartesianPoseTask(robot, frame='tool', axes=['z'], lower=[p0[2] - 0.03], gain=20.0,
                          name='obstacle'),
        JointTorqueTask(robot, lower=-5.0, upper=5.0, gain=20.0, name='static_torques'),
        CartesianPoseTask(robot, frame='tool', axes=['x', 'y', 'z'],
                          equal=_circle(p0 - [0, 0.05, 0], 0.05, 0.2), gain=10.0,
                          name='circle'),
        CartesianPoseTask(robot, frame='tool', axes=['rx', 'ry', 'rz'], equal='init',
                          gain=10.0, name='orientation'),
        JointPositionTask(robot, equal=robot.q_home, gain=1.0, name='posture'),
    ]


def icub_stack(robot):
    """Table 3.7 on the iCub: 7 levels."""
    torso = [j for j in robot.joint_names if 'torso' in j]
    pl = _tool_pose(robot, robot.q_home, 'l_contact')
    return [
        WrenchTask(robot, frame='l_contact', axes=['fz'], equal=-1.0, gain=5.0, name='l_force'),
        CartesianPoseTask(robot, frame='l_contact', axes=['x', 'y'],
                          equal=_circle(pl, 0.03, 0.2, plane=(0, 1), select=(0, 1)), gain=5.0,
                          name='l_wipe'),
        CartesianPoseTask(robot, frame='r_palm', axes=['rx', 'ry'], equal='init', gain=5.0,
                          name='cup_upright'),
        CartesianPoseTask(robot, frame='r_palm', axes=['x', 'y', 'z'], equal='init', gain=5.0,
                          name='cup_position'),
        CartesianPoseTask(robot, frame='l_palm', axes=['rx', 'ry', 'rz'], equal='init',
                          gain=5.0, name='l_orientation'),
        JointPositionTask(robot, joints=torso, equal='init', gain=1.0, name='torso'),
        JointPositionTask(robot, equal='init', gain=1.0, name='posture'),
    ]


def _busy(count):
    """A fixed piece of pure Python work (the machine baseline)."""
    x = 0
    for i in range(count):
        x += i
    return x


def calibrate_baseline(seconds):
    """The ``_busy`` count that takes about ``seconds`` here (median of 50 runs)."""
    count = 1000
    runs = []
    for _ in range(50):
        t0 = time.perf_counter()
        _busy(count)
        runs.append(time.perf_counter() - t0)
    return max(1, int(count * seconds / float(np.median(runs))))


def _closed_loop(spg, robot, ticks, progress, budget=None, baseline=None):
    """Run ``ticks`` closed-loop ticks (fewer if ``budget`` seconds run out first).

    With a ``baseline`` count, time ``_busy(baseline)`` after each tick too (see module doc).
    """
    plant = JointImpedancePlant(robot, robot.q_home, substeps=1)
    q, qd, t = plant.q, plant.qdot, 0.0
    times = np.empty(ticks)
    base = np.empty(ticks if baseline else 0)
    statuses = {}
    deadline = None if budget is None else time.perf_counter() + budget
    for i in range(ticks):
        if deadline is not None and time.perf_counter() > deadline:
            print(f'    ... stopped after {i} ticks: the {budget:g} s budget ran out',
                  file=sys.stderr)
            return times[:i], statuses, base[:i]
        q_v = spg.step(q, qd, t)
        times[i] = spg.info.tick_time
        if baseline:
            t0 = time.perf_counter()
            _busy(baseline)
            base[i] = time.perf_counter() - t0
        statuses[spg.info.status] = statuses.get(spg.info.status, 0) + 1
        q, qd, t = plant.step(q_v)
        if progress and i % max(1, ticks // 4) == 0 and i:
            print(f'    ... {i}/{ticks} ticks', file=sys.stderr)
    return times, statuses, base


def _stats(times):
    if times.size == 0:
        return {'p50_us': float('nan'), 'p99_us': float('nan'), 'max_us': float('nan'),
                'ticks': 0, 'over_1ms': 0}
    us = times * 1e6
    return {'p50_us': float(np.median(us)), 'p99_us': float(np.percentile(us, 99)),
            'max_us': float(us.max()), 'ticks': int(us.size),
            'over_1ms': int(np.count_nonzero(us > 1000.0))}


def bench_stack(name, robot, make_stack, solvers, ticks, progress=True, slow_ticks=None,
                slow_budget=None):
    """Tick times of one stack per solver.

    Solvers other than DAQP run ``slow_ticks`` ticks at most, within ``slow_budget`` seconds
    (proxsuite can stall for seconds per tick).
    """
    rows = []
    for solver in solvers:
        slow = solver != 'daqp'
        n_ticks = ticks if not slow or slow_ticks is None else min(ticks, slow_ticks)
        budget = slow_budget if slow else None
        spg = SetPointGenerator(robot, make_stack(robot), solver=solver)
        warm, _, _ = _closed_loop(spg, robot, 200, False, budget)  # warm-up
        baseline = None if slow else calibrate_baseline(float(np.median(warm)))
        gc.collect()
        gc.disable()
        try:
            times, statuses, base = _closed_loop(spg, robot, n_ticks, progress, budget,
                                                 baseline)
        finally:
            gc.enable()
        row = {'stack': name, 'solver': solver, 'levels': len(spg.info.level_names)}
        row.update(_stats(times))
        row['status'] = statuses
        if baseline:
            row['baseline'] = _stats(base)
        rows.append(row)
    return rows


def bench_native_ratio(name, robot, make_stack, ticks):
    """The tick with the C kernels vs their numpy code: two closed loops, interleaved."""
    if kernels.native is None:
        return None
    fast = SetPointGenerator(robot, make_stack(robot), kernels=kernels.native)
    slow = SetPointGenerator(robot, make_stack(robot), kernels=kernels.reference)
    for spg in (fast, slow):
        _closed_loop(spg, robot, 200, False)  # warm-up
    a, b = (_stats(t) for t in _interleaved(robot, (fast, slow), ticks))
    return {'stack': name, 'native': a, 'numpy': b, 'ratio_p50': a['p50_us'] / b['p50_us'],
            'ratio_p99': a['p99_us'] / b['p99_us']}


def _interleaved(robot, spgs, ticks):
    """Tick times [s] of two SPGs in closed loops with their own plants, tick by tick.

    Who goes first alternates every tick; the garbage collector is off during the loops.
    """
    loops = []
    for spg in spgs:
        plant = JointImpedancePlant(robot, robot.q_home, substeps=1)
        loops.append([spg, plant, (plant.q, plant.qdot, 0.0), np.empty(ticks)])
    gc.collect()
    gc.disable()
    try:
        for i in range(ticks):
            for k in (0, 1) if i % 2 == 0 else (1, 0):
                loop = loops[k]
                spg, plant, state, times = loop
                q_v = spg.step(*state)
                times[i] = spg.info.tick_time
                loop[2] = plant.step(q_v)
    finally:
        gc.enable()
    return [loop[3] for loop in loops]


def _python_calls(spg, robot, ticks=100):
    """Calls per closed-loop tick as ``sys.setprofile`` sees them.

    Python functions and builtins; not the methods of Cython classes (``daqp.Model.update``
    and ``solve`` are not counted), nor calls of types.
    """
    plant = JointImpedancePlant(robot, robot.q_home, substeps=1)
    state = (plant.q, plant.qdot, 0.0)
    count = [0]

    def profile(frame, event, arg):
        if event in ('call', 'c_call'):
            count[0] += 1

    for _ in range(ticks):
        sys.setprofile(profile)
        q_v = spg.step(*state)
        sys.setprofile(None)
        state = plant.step(q_v)
    return count[0] / ticks


def bench_daqp_native_ratio(name, robot, make_stack, ticks):
    """The tick with the level solves from C vs through DAQP's Python module, interleaved.

    Two closed loops (both with the C kernels of the tick), tick by tick, who goes first
    alternating; and each loop's Python calls per tick. None where the C module is not built.
    """
    if daqp_cascade.native is None or kernels.native is None:
        return None
    spgs, calls = [], []
    for on in (True, False):
        spg = SetPointGenerator(robot, make_stack(robot), kernels=kernels.native)
        if not on:
            spg.solver.native_daqp = None  # the cascade's Python-module path
        _closed_loop(spg, robot, 200, False)  # warm-up
        calls.append(_python_calls(spg, robot))
        spgs.append(spg)
    a, b = (_stats(t) for t in _interleaved(robot, spgs, ticks))
    return {'stack': name, 'c': a, 'python': b, 'ratio_p50': a['p50_us'] / b['p50_us'],
            'ratio_p99': a['p99_us'] / b['p99_us'], 'calls_c': calls[0],
            'calls_python': calls[1]}


def bench_pink(ticks):
    """Our 2-level strict stack vs pink's weighted solve, interleaved in one loop."""
    import pink  # the library compared with: needed by this benchmark only

    robot = RobotModel.from_config('lbr_iiwa14')
    dt = 0.002
    zeros = np.zeros(robot.n)

    def ours(pspm):
        spg = SetPointGenerator(robot, [
            CartesianPoseTask(robot, frame='tool', equal='init', gain=1.0, name='pose'),
            JointPositionTask(robot, equal=robot.q_home, gain=1.0, name='posture')],
            torque_limits=False, pspm=pspm)
        q = [robot.q_home.copy()]

        def tick(i):
            q[0] = spg.step(q[0], zeros, i * dt)
        return tick

    # without the passivity layer too (pink has none): the like-for-like tick
    steps = (ours(True), ours(False), _pink_ticker(pink, robot, dt))
    gc.collect()
    gc.disable()
    try:
        times = np.empty((3, ticks))
        for i in range(ticks):  # rotate who goes first (caches, frequency scaling)
            for k in range(3):
                j = (i + k) % 3
                t0 = time.perf_counter()
                steps[j](i)
                times[j, i] = time.perf_counter() - t0
    finally:
        gc.enable()
    a, c, b = (_stats(t) for t in times)
    return {'ours': a, 'pink': b, 'ratio_p50': a['p50_us'] / b['p50_us'],
            'ratio_p99': a['p99_us'] / b['p99_us'], 'ours_no_pspm': c,
            'ratio_no_pspm_p50': c['p50_us'] / b['p50_us'],
            'ratio_no_pspm_p99': c['p99_us'] / b['p99_us']}


def _pink_ticker(pink, robot, dt):
    """The pink tick on the same two tasks, weighted; its configuration does the kinematics."""
    from pink.tasks import FrameTask, PostureTask

    frame_name = robot.frames['tool']
    config = pink.Configuration(robot.model, robot.create_data(), robot.q_home.copy())
    pose_task = FrameTask(frame_name, position_cost=1.0, orientation_cost=1.0, gain=1.0)
    pose_task.set_target(config.get_transform_frame_to_world(frame_name))
    posture_task = PostureTask(cost=1e-3)
    posture_task.set_target(robot.q_home.copy())
    q = [robot.q_home.copy()]

    def tick(i):
        config.update(q[0])
        v = pink.solve_ik(config, [pose_task, posture_task], dt, solver='daqp')
        q[0] = pin.integrate(robot.model, q[0], v * dt)
    return tick


def bench_first_ticks(repeats=20):
    """The first tick of a stack and the tick of a switch to a stack of another shape.

    Timed apart from the steady ticks (a robot misses a command on any tick over its period).
    Each repeat: a new SPG with the LBR Table 4.1 stack, 100 closed-loop ticks, a switch to the
    Table 4.2 stack (other levels), 100 more. Returns the first-tick, switch-tick and
    steady-tick statistics [us] over the repeats, and the max of everything.
    """
    robot = RobotModel.from_config('lbr_iiwa14')
    tasks = find_config_dir() / 'tasks'
    second = TaskStack.from_file(str(tasks / 'table_4_2_orientation_box.yaml'))
    times = {mode: ([], [], []) for mode in ('prepared', 'lazy')}
    gc.disable()
    try:
        for r in range(2 * repeats):  # the two modes interleaved
            mode = ('prepared', 'lazy')[r % 2]
            first_t, switch_t, steady = times[mode]
            spg = SetPointGenerator(robot, None, dt=0.002)
            if mode == 'lazy':  # the baseline: models built at the tick that first needs them
                spg.solver.prepare = lambda dims, equalities: None  # type: ignore[method-assign]
            spg.set_stack(lbr_stack(robot))
            q, qdot = np.array(robot.q_home, dtype=float), np.zeros(robot.n)
            for k in range(200):
                if k == 100:
                    spg.set_stack(second)  # accepted between ticks, as the node does
                t0 = time.perf_counter()
                q_v = spg.step(q, qdot, k * 0.002)
                dt = time.perf_counter() - t0
                (first_t if k == 0 else switch_t if k == 100 else steady).append(dt)
                qdot, q = (q_v - q) / 0.002, q_v
    finally:
        gc.enable()
    return {'repeats': repeats, **{
        mode: {'first': _stats(np.array(f)), 'switch': _stats(np.array(s)),
               'steady': _stats(np.array(st))} for mode, (f, s, st) in times.items()}}


def _process_first(warm_up):
    """First, switch and steady ticks [us] of the first SPG of this process (LBR, as above)."""
    robot = RobotModel.from_config('lbr_iiwa14')
    second = TaskStack.from_file(str(find_config_dir() / 'tasks' /
                                     'table_4_2_orientation_box.yaml'))
    spg = SetPointGenerator(robot, None, dt=0.002, warm_up=warm_up)
    spg.set_stack(lbr_stack(robot))
    q, qdot = np.array(robot.q_home, dtype=float), np.zeros(robot.n)
    times = np.empty(200)
    gc.disable()
    try:
        for k in range(200):
            if k == 100:
                spg.set_stack(second)
            t0 = time.perf_counter()
            q_v = spg.step(q, qdot, k * 0.002)
            times[k] = time.perf_counter() - t0
            qdot, q = (q_v - q) / 0.002, q_v
    finally:
        gc.enable()
    us = times * 1e6
    p50 = float(np.median(np.delete(us, [0, 100])))
    return {'first_us': float(us[0]), 'switch_us': float(us[100]), 'steady_p50_us': p50,
            'first_ratio': float(us[0]) / p50, 'switch_ratio': float(us[100]) / p50}


def bench_process_first_ticks(runs=3):
    """The first and switch tick of the first SPG of a process, with and without the warm-up.

    Each run starts two fresh interpreters (:func:`_process_first`, the SPG built with
    ``warm_up=True`` and with ``warm_up=False``); the first tick of a process pays for
    Python's bytecode specialization and the libraries' first calls, which a process that
    ran other SPGs before has paid. Returns the runs and their medians.
    """
    root = Path(__file__).resolve().parent.parent
    code = ('import json, sys; from benchmarks.bench import _process_first; '
            'print(json.dumps(_process_first(sys.argv[1] == "1")))')
    out = {'runs': runs}
    for mode, flag in (('warm_up', '1'), ('no_warm_up', '0')):
        rows = []
        for _ in range(runs):
            proc = subprocess.run([sys.executable, '-c', code, flag], cwd=root, check=True,
                                  capture_output=True, text=True)
            rows.append(json.loads(proc.stdout.strip().splitlines()[-1]))
        out[mode] = {'runs': rows, **{key: float(np.median([r[key] for r in rows]))
                                      for key in rows[0]}}
    return out


def run_benchmarks(ticks=20000, solvers=('daqp', 'proxsuite'), progress=True,
                   slow_ticks=300, slow_budget=60.0, first_runs=3):
    """Run all benchmarks; return a JSON-friendly dict."""
    out = {'ticks': ticks, 'stacks': [],
           'implementation': f'{kernels.describe()}; {daqp_cascade.describe()}'}
    lbr = RobotModel.from_config('lbr_iiwa14')
    icub = RobotModel.from_config('icub_upper_body')
    for name, robot, make in (('lbr_table_4_1', lbr, lbr_stack),
                              ('icub_table_3_7', icub, icub_stack)):
        if progress:
            print(f'  {name} ...', file=sys.stderr)
        out['stacks'] += bench_stack(name, robot, make, solvers, ticks, progress, slow_ticks,
                                     slow_budget)
    for key, ratio in (('native', bench_native_ratio),
                       ('daqp_native', bench_daqp_native_ratio)):
        out[key] = []
        for name, robot, make in (('lbr_table_4_1', lbr, lbr_stack),
                                  ('icub_table_3_7', icub, icub_stack)):
            if progress:
                print(f'  {key}_ratio {name} ...', file=sys.stderr)
            row = ratio(name, robot, make, ticks)
            if row is not None:
                out[key].append(row)
    if progress:
        print('  pink_ratio ...', file=sys.stderr)
    out['pink'] = bench_pink(ticks)
    if progress:
        print('  first and stack-switch ticks ...', file=sys.stderr)
    out['first_ticks'] = bench_first_ticks()
    out['process_first_ticks'] = bench_process_first_ticks(first_runs)
    from benchmarks.collision_bench import bench_collision
    out['collision'] = bench_collision(max(10, ticks // 4), progress)
    return out


#: issue 32's targets [us] on a quiet 2-core machine (and no LBR tick over 1 ms)
TARGETS = {'lbr_table_4_1': {'p50': 55.0, 'p99': 100.0, 'max': 1000.0},
           'icub_table_3_7': {'p50': 120.0, 'p99': 200.0}}
#: issue 32's target of ours / pink's weighted solve (p50)
PINK_TARGET = 0.5


def _format_first_ticks(res):
    """The lines of the first-tick and stack-switch-tick rows."""
    lines = []
    f = res.get('first_ticks')
    if f:
        lines += ['', f"LBR first tick and stack-switch tick ({f['repeats']} repeats each, "
                  'interleaved): solver models built when a stack is accepted (prepared) vs '
                  'at the tick that first needs them (lazy, the old way):']
        for mode in ('prepared', 'lazy'):
            for key in ('first', 'switch', 'steady'):
                st = f[mode][key]
                lines.append(f"  {mode:<9}{key:<7}p50 {st['p50_us']:8.1f} us  p99 "
                             f"{st['p99_us']:8.1f} us  max {st['max_us']:8.1f} us")
        p, lazy = f['prepared'], f['lazy']
        worst = max(p['first']['max_us'], p['switch']['max_us'])
        ratio = {key: p[key]['p50_us'] / lazy[key]['p50_us'] for key in ('first', 'switch')}
        lines.append(f"  first and switch ticks <= 1 ms (prepared): "
                     f"{'met' if worst <= 1000.0 else 'MISSED'} (max {worst:.0f} us); ratio "
                     f"prepared/lazy p50: first {ratio['first']:.2f}, switch "
                     f"{ratio['switch']:.2f}")
        lines.append(f"  prepared, to the steady p50: first "
                     f"{p['first']['p50_us'] / p['steady']['p50_us']:.2f}, switch "
                     f"{p['switch']['p50_us'] / p['steady']['p50_us']:.2f} (target <= 3)")
    pf = res.get('process_first_ticks')
    if pf:
        lines += ['', f"LBR first tick of a process (a fresh interpreter per run, median of "
                  f"{pf['runs']}), with the construction's warm-up and without it:"]
        for mode in ('warm_up', 'no_warm_up'):
            m = pf[mode]
            lines.append(f"  {mode:<11}first {m['first_us']:6.0f} us  switch "
                         f"{m['switch_us']:6.0f} us  steady p50 {m['steady_p50_us']:5.0f} us:"
                         f"  first/p50 {m['first_ratio']:.2f}  switch/p50 "
                         f"{m['switch_ratio']:.2f}  (target <= 3)")
    return lines


def format_report(res):
    lines = [f"SPG full tick, closed loop (plant not timed); tick arithmetic: "
             f"{res.get('implementation', '?')}",
             f"{'stack':<16}{'solver':<11}{'levels':>6}{'ticks':>7}{'p50 us':>10} {'p99 us':>10}"
             f" {'max us':>10}  {'target':<27}status"]
    for r in res['stacks']:
        goals = TARGETS.get(r['stack'], {})
        ok = all(r[f'{key}_us'] <= bound for key, bound in goals.items())
        target = ','.join(f'{key}<={bound:.0f}' for key, bound in goals.items()) or '-'
        lines.append(f"{r['stack']:<16}{r['solver']:<11}{r['levels']:>6}{r['ticks']:>7}"
                     f"{r['p50_us']:>10.1f} {r['p99_us']:>10.1f} {r['max_us']:>10.1f}  "
                     f"{target:<27}{'met' if ok else 'MISSED'} {r['status']}")
    for r in res['stacks']:
        if 'baseline' in r:
            b = r['baseline']
            lines.append(f"  {r['stack']}: SPG ticks over 1 ms: {r['over_1ms']}; machine "
                         f"baseline next to it (fixed work, p50 {b['p50_us']:.0f} us): p99 "
                         f"{b['p99_us']:.0f} us, max {b['max_us']:.0f} us, {b['over_1ms']} "
                         f"over 1 ms")
    if res.get('native'):
        lines += ['', 'C kernels vs their numpy reference code (ifc_spg.kernels), two closed '
                  'loops interleaved:']
        for r in res['native']:
            a, b = r['native'], r['numpy']
            lines.append(f"  {r['stack']:<16}C p50 {a['p50_us']:.1f} / p99 {a['p99_us']:.1f} us,"
                         f" numpy {b['p50_us']:.1f} / {b['p99_us']:.1f} us: ratio "
                         f"{r['ratio_p50']:.2f} / {r['ratio_p99']:.2f}")
    if res.get('daqp_native'):
        lines += ['', "Level solves from C vs through DAQP's Python module "
                  '(ifc_spg.cascade._daqp_native), two closed loops interleaved:']
        for r in res['daqp_native']:
            a, b = r['c'], r['python']
            lines.append(f"  {r['stack']:<16}C p50 {a['p50_us']:.1f} / p99 {a['p99_us']:.1f} us,"
                         f" Python {b['p50_us']:.1f} / {b['p99_us']:.1f} us: ratio "
                         f"{r['ratio_p50']:.2f} / {r['ratio_p99']:.2f}; Python calls per "
                         f"tick {r['calls_c']:.0f} / {r['calls_python']:.0f}")
    p = res['pink']
    lines += ['', '2-level strict stack (pose + posture) vs pink weighted solve (daqp), '
              'interleaved:',
              f"  ours p50 {p['ours']['p50_us']:.1f} us  p99 {p['ours']['p99_us']:.1f} us  "
              f"max {p['ours']['max_us']:.1f} us",
              f"  pink p50 {p['pink']['p50_us']:.1f} us  p99 {p['pink']['p99_us']:.1f} us  "
              f"max {p['pink']['max_us']:.1f} us",
              f"  ratio ours/pink: p50 {p['ratio_p50']:.2f}  p99 {p['ratio_p99']:.2f}  "
              f"(target <= {PINK_TARGET:g}: "
              f"{'met' if p['ratio_p50'] <= PINK_TARGET else 'MISSED'})",
              f"  ours without PSPM (pink has no passivity layer): p50 "
              f"{p['ours_no_pspm']['p50_us']:.1f} us  p99 {p['ours_no_pspm']['p99_us']:.1f} us; "
              f"ratio p50 {p['ratio_no_pspm_p50']:.2f}  p99 {p['ratio_no_pspm_p99']:.2f}"]
    lines += _format_first_ticks(res)
    if res.get('collision'):
        from benchmarks.collision_bench import format_collision
        lines += ['', format_collision(res['collision'])]
    return '\n'.join(lines)


_FIGURE = Path(__file__).resolve().parent.parent / 'docs' / 'figures' / 'tick_scaling.png'


def _scaling(ticks, json_path, figure):
    """``--scaling``: run :mod:`benchmarks.scaling_bench`, print, write the JSON and figure."""
    from benchmarks.scaling_bench import format_scaling, plot, run_scaling

    res = run_scaling(ticks)
    print(format_scaling(res))
    if json_path:
        with open(json_path, 'w') as f:
            json.dump(res, f, indent=1)
    if figure:
        plot(res, figure)
        print(f'figure: {figure}')
    return 0


def main(argv=None):
    """Entry point of ``ifc-spg bench``."""
    p = argparse.ArgumentParser(prog='ifc-spg bench', description=__doc__.split('\n\n')[0])
    p.add_argument('--ticks', type=int, default=None,
                   help='ticks per row (default 20000; with --scaling 2000 per point)')
    p.add_argument('--quick', action='store_true', help='2000 ticks per row')
    p.add_argument('--scaling', action='store_true',
                   help='only the cost curve: tick p50/p99 against DoF (7, 17, 34-joint '
                        'chains), levels (1-10) and rows per level (1-12), with fitted '
                        'exponents (benchmarks/scaling_bench.py; about 30 s)')
    p.add_argument('--figure', default=str(_FIGURE),
                   help='with --scaling: the PNG of the three curves (default '
                        "docs/figures/tick_scaling.png of the checkout; '' for none)")
    p.add_argument('--solvers', default='daqp,proxsuite', help='comma-separated solvers')
    p.add_argument('--proxsuite-ticks', type=int, default=300,
                   help='ticks per proxsuite row (default 300: it stalls for up to ~0.2 s '
                        'on degenerate levels, so 20 000 ticks take minutes)')
    p.add_argument('--proxsuite-budget', type=float, default=60.0,
                   help='seconds per proxsuite row, warm-up included (default 60)')
    p.add_argument('--json', help='also write the results to this JSON file')
    args = p.parse_args(argv)
    ticks = 2000 if args.quick else 20000 if args.ticks is None else args.ticks
    if args.scaling and not args.quick and args.ticks is None:
        ticks = 2000
    if ticks < 1:
        p.error('--ticks must be >= 1')
    if args.scaling:
        return _scaling(ticks, args.json, args.figure)
    res = run_benchmarks(ticks, tuple(s for s in args.solvers.split(',') if s),
                         slow_ticks=args.proxsuite_ticks, slow_budget=args.proxsuite_budget)
    print(format_report(res))
    if args.json:
        with open(args.json, 'w') as f:
            json.dump(res, f, indent=1)
    return 0


if __name__ == '__main__':
    sys.exit(main())
