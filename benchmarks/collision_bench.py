"""Collision-avoidance benchmark (part of ``ifc-spg bench``).

Two measurements, each side by side in one process, tick by tick interleaved so that the
machine's load affects both alike:

- ``tick``: the full SPG tick (``info.tick_time``) with and without a
  ``collision_avoidance`` level on top of the same stack (tool position + posture), each
  SPG in its own closed loop with a tracking plant: the LBR iiwa 14 (self pairs and three
  obstacles near the wrist), the ACCREA dual arm (its self pairs, both arms) and the iCub
  upper body (its self pairs, both hands); where the
  C++ narrowphase is built, a third loop with the level on pinocchio's Python bindings
  (the A/B of :mod:`ifc_spg.geometry.narrowphase`);
- ``mink``: the rows of our level (``task.level``: distances, cull, witness points,
  distance Jacobian rows, at a given q) next to mink's ``CollisionAvoidanceLimit``
  (``compute_qp_inequalities`` after ``Configuration.update``, its own broadphase on)
  for the same model, the same geometry pairs and the same configurations (the recorded
  q_v of the closed loop). mink uses MuJoCo's ``mj_geomDistance``; our distances are
  coal's on pinocchio's model of the same MJCF.

The iCub upper body (its self pairs, both hands reaching) gets the ``tick`` measurement only:
its shapes are the convex hulls of the URDF's collision meshes, which its MJCF lacks.
"""

import contextlib
import gc
import time

import numpy as np

from ifc_spg import RobotModel, SetPointGenerator, TaskStack
from ifc_spg.geometry import narrowphase
from ifc_spg.kinematics import Kinematics

__all__ = ['bench_collision', 'format_collision']

DT = 0.002
OBSTACLES = [
    {'name': 'ball', 'shape': 'sphere', 'radius': 0.06, 'position': [0.5, 0.25, 0.55]},
    {'name': 'crate', 'shape': 'box', 'size': [0.2, 0.1, 0.3], 'position': [0.45, -0.3, 0.35]},
    {'name': 'post', 'shape': 'cylinder', 'radius': 0.04, 'length': 1.2,
     'position': [0.3, 0.35, 0.6]},
]
MARGIN, INFLUENCE, GAIN = 0.02, 0.1, 0.5


def _stack(robot, avoid, pairs, obstacles, reach):
    tasks = [{'name': f'reach_{frame}', 'type': 'cartesian_pose', 'frame': frame,
              'subspace': ['x', 'y', 'z'],
              'equal': {'trajectory': 'sine', 'amplitude': [0.0, 0.15, 0.05],
                        'frequency': 0.25}} for frame in reach]
    tasks.append({'name': 'posture', 'type': 'joint_position', 'equal': 'init', 'gain': 0.5})
    if avoid:
        tasks.insert(0, {'name': 'avoid', 'type': 'collision_avoidance', 'pairs': pairs,
                         'margin': MARGIN, 'influence': INFLUENCE, 'gain': GAIN})
    return TaskStack.from_dict({'version': 1, 'name': 'bench', 'robot': robot.name,
                                'obstacles': obstacles, 'tasks': tasks})


CASES = {
    'lbr_iiwa14': dict(pairs=['self', {'name': 'wrist', 'links': ['link5', 'link6', 'link7'],
                                       'obstacles': ['ball', 'crate', 'post']}],
                       obstacles=OBSTACLES, reach=['tool']),
    'accrea_dual_arm': dict(pairs=['self'], obstacles=[], reach=['l_tool', 'r_tool']),
    # the shapes are convex hulls of the URDF's collision meshes, which the MJCF MuJoCo loads
    # does not have: mink would check other shapes, so no mink row
    'icub_upper_body': dict(pairs=['self'], obstacles=[], reach=['l_hand', 'r_hand'],
                            mink="no mink row: our shapes are the convex hulls of the URDF's "
                                 "collision meshes, which the MJCF MuJoCo loads does not have"),
}


def _stats(times):
    us = np.asarray(times) * 1e6
    return {'p50_us': float(np.median(us)), 'p99_us': float(np.percentile(us, 99)),
            'max_us': float(us.max()), 'ticks': int(us.size)}


@contextlib.contextmanager
def _pinocchio_narrowphase():
    """New pair queries use pinocchio's Python bindings, not the C++ narrowphase (A/B)."""
    native = narrowphase.native
    narrowphase.native = None
    try:
        yield
    finally:
        narrowphase.native = native


def bench_tick(name, ticks):
    """The tick with and without the avoidance level (closed loops, interleaved).

    Where the C++ narrowphase is used (:mod:`ifc_spg.geometry.narrowphase`), a third loop
    runs the same level on pinocchio's Python bindings (``with_pinocchio``), interleaved too.
    """
    robot = RobotModel.from_config(name)
    case = CASES[name]

    def spg(avoid):
        return SetPointGenerator(robot, _stack(robot, avoid, case['pairs'], case['obstacles'],
                                               case['reach']), dt=DT)

    spgs = [spg(True), spg(False)]
    if narrowphase.native is not None:
        with _pinocchio_narrowphase():
            spgs.append(spg(True))
    loops = len(spgs)
    states = [robot.q_home.copy() for _ in spgs]
    qdots = [np.zeros(robot.n) for _ in spgs]
    times = np.empty((loops, ticks))
    trajectory = np.empty((ticks, robot.n))
    for k in range(200):  # warm-up
        for i in range(loops):
            states[i] = spgs[i].step(states[i], qdots[i], k * DT)
            qdots[i] = spgs[i].qdot_v.copy()
    gc.collect()
    gc.disable()
    try:
        for k in range(ticks):
            for i in np.roll(np.arange(loops), k % loops).tolist():
                q_v = spgs[i].step(states[i], qdots[i], (k + 200) * DT)
                times[i, k] = spgs[i].info.tick_time
                states[i], qdots[i] = q_v, spgs[i].qdot_v.copy()
            trajectory[k] = states[0]
    finally:
        gc.enable()
    task = spgs[0].tasks[0]
    near = task.report().as_dict()['groups']
    with_, without = _stats(times[0]), _stats(times[1])
    out = {'robot': name, 'pairs': len(task.pairs), 'rows': task.dim,
           'groups': {g: len(i) for g, i in task.groups},
           'narrowphase': narrowphase.describe(), 'with': with_, 'without': without,
           'added_p50_us': with_['p50_us'] - without['p50_us'],
           'added_p99_us': with_['p99_us'] - without['p99_us'],
           'added_max_us': with_['max_us'] - without['max_us'],
           'status': spgs[0].info.status, 'last_min_distance': near,
           'trajectory': trajectory, 'task': task}
    if loops == 3:
        old = out['with_pinocchio'] = _stats(times[2])
        out['added_p50_pinocchio_us'] = old['p50_us'] - without['p50_us']
        out['added_p99_pinocchio_us'] = old['p99_us'] - without['p99_us']
    return out


def _mj_shape(g):
    """MuJoCo geom type and size of a coal shape (the benchmark's obstacles)."""
    import mujoco

    name = type(g).__name__
    if name == 'Sphere':
        return mujoco.mjtGeom.mjGEOM_SPHERE, [g.radius, 0, 0]
    if name == 'Box':
        return mujoco.mjtGeom.mjGEOM_BOX, list(g.halfSide)
    kind = mujoco.mjtGeom.mjGEOM_CYLINDER if name == 'Cylinder' else mujoco.mjtGeom.mjGEOM_CAPSULE
    return kind, [g.radius, g.halfLength, 0]


def _mink_model(robot, task):
    """The robot's MJCF in MuJoCo with the obstacles as world geoms (every geom collides)."""
    import mujoco

    from sim_bridge.models import robot_mjcf_spec

    spec = robot_mjcf_spec(robot)
    geometry = task.geometry
    for name, index in geometry.obstacles.items():
        obj = geometry.model.geometryObjects[index]
        kind, size = _mj_shape(obj.geometry)
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, np.asarray(obj.placement.rotation).reshape(-1))
        spec.worldbody.add_geom(name=f'obstacle:{name}', type=kind, size=size,
                                pos=list(obj.placement.translation), quat=list(quat))
    for geom in spec.geoms:  # mink drops pairs that fail contype/conaffinity
        geom.contype, geom.conaffinity = 1, 1
    return spec.compile()


def bench_mink(result, repeats=1):
    """Our level's rows vs mink's CollisionAvoidanceLimit rows, same pairs and q sequence."""
    import mink  # the library compared with: needed by this benchmark only
    import mujoco

    task = result['task']
    robot = task.robot
    model = _mink_model(robot, task)
    pairs = [([a], [b]) for a, b in task.names]
    limit = mink.CollisionAvoidanceLimit(
        model, pairs, minimum_distance_from_collisions=MARGIN,
        collision_detection_distance=INFLUENCE, broadphase=True)
    config = mink.Configuration(model)
    qpos = np.array([model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j)]
                     for j in robot.joint_names])
    kin = Kinematics(robot)
    zeros = np.zeros(robot.n)
    q_mj = config.q.copy()
    trajectory = result['trajectory']
    times = np.empty((2, len(trajectory) * repeats))
    rows = [0, 0]
    gc.collect()
    gc.disable()
    try:
        for k, q in enumerate(np.tile(trajectory, (repeats, 1))):
            q_mj[qpos] = q
            for i in ((0, 1) if k % 2 == 0 else (1, 0)):
                t0 = time.perf_counter()
                if i == 0:
                    kin.update(q, zeros, q)
                    level = task.level(kin, 0.0)
                else:
                    config.update(q_mj)
                    ineq = limit.compute_qp_inequalities(config, DT)
                times[i, k] = time.perf_counter() - t0
            rows[0] += int(np.count_nonzero(np.isfinite(level.lower)))
            rows[1] += 0 if ineq.G is None else int(np.count_nonzero(
                np.abs(ineq.G).sum(axis=1) > 0))
    finally:
        gc.enable()
    ours, theirs = _stats(times[0]), _stats(times[1])
    n = len(times[0])
    return {'robot': robot.name, 'pairs': len(task.pairs), 'mink_pairs': len(limit.geom_id_pairs),
            'ours': ours, 'mink': theirs, 'ratio_p50': ours['p50_us'] / theirs['p50_us'],
            'ratio_p99': ours['p99_us'] / theirs['p99_us'],
            'active_rows_per_tick': (rows[0] / n, rows[1] / n)}


def bench_collision(ticks=5000, progress=True):
    """Run both measurements (the iCub: the tick only); a JSON-friendly dict."""
    import sys

    out = {'tick': [], 'mink': []}
    for name in CASES:
        if progress:
            print(f'  collision avoidance tick {name} ...', file=sys.stderr)
        res = bench_tick(name, ticks)
        if 'mink' in CASES[name]:
            out.setdefault('mink_skipped', {})[name] = CASES[name]['mink']
        else:
            try:
                out['mink'].append(bench_mink(res))
            except ImportError:
                out['mink_missing'] = 'mink is not installed (pip install mink==1.3.0)'
        res.pop('trajectory')
        res.pop('task')
        out['tick'].append(res)
    return out


def format_collision(res):
    """The report lines of :func:`bench_collision`."""
    lines = ['Collision avoidance (margin 0.02 m, influence 0.1 m): full tick with and '
             'without the level, two closed loops interleaved:']
    for r in res['tick']:
        a, b = r['with'], r['without']
        lines.append(f"  {r['robot']:<16} {r['pairs']:>4} pairs {r['groups']}, {r['rows']} rows: "
                     f"with p50 "
                     f"{a['p50_us']:.1f} / p99 {a['p99_us']:.1f} / max {a['max_us']:.0f} us, "
                     f"without {b['p50_us']:.1f} / {b['p99_us']:.1f} / {b['max_us']:.0f} us; "
                     f"added p50 {r['added_p50_us']:.1f} us, p99 {r['added_p99_us']:.1f} us; "
                     f"narrowphase: {r['narrowphase']}")
        if 'with_pinocchio' in r:
            c = r['with_pinocchio']
            lines.append(f"  {'':<16} the same level on pinocchio's Python bindings "
                         f"(interleaved): p50 {c['p50_us']:.1f} / p99 {c['p99_us']:.1f} / max "
                         f"{c['max_us']:.0f} us; added p50 {r['added_p50_pinocchio_us']:.1f} us"
                         f", p99 {r['added_p99_pinocchio_us']:.1f} us")
    if res.get('mink'):
        lines.append('  rows of the level (ours: distances, cull, rows at q) vs mink '
                     'CollisionAvoidanceLimit.compute_qp_inequalities (+ update), same pairs '
                     'and q, interleaved:')
    for r in res.get('mink', []):
        a, b = r['ours'], r['mink']
        lines.append(f"  {r['robot']:<16} ours p50 {a['p50_us']:.1f} / p99 {a['p99_us']:.1f} /"
                     f" max {a['max_us']:.0f} us, mink ({r['mink_pairs']} pairs) p50 "
                     f"{b['p50_us']:.1f} / p99 {b['p99_us']:.1f} / max {b['max_us']:.0f} us; "
                     f"ratio ours/mink p50 {r['ratio_p50']:.2f}, p99 {r['ratio_p99']:.2f}; "
                     f"active rows per tick {r['active_rows_per_tick'][0]:.1f} / "
                     f"{r['active_rows_per_tick'][1]:.1f}")
    for name, why in res.get('mink_skipped', {}).items():
        lines.append(f'  {name:<16} {why}')
    if res.get('mink_missing'):
        lines.append(f"  mink: {res['mink_missing']}")
    return '\n'.join(lines)


if __name__ == '__main__':
    import sys
    ticks = int(sys.argv[1]) if len(sys.argv) > 1 else 5000
    print(format_collision(bench_collision(ticks)))
