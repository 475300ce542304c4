"""Closed loops of the Table 4.1 and 3.7 stacks whose q_v sequences are recorded in
``test/data/tick_recorded.npz`` (``test_tick_recorded``): each run ticks one stack, switches
to a second at tick ``SWITCH`` and runs to ``TICKS``, on :class:`JointImpedancePlant`.

Each run is recorded with the C kernels and with their numpy reference (``<run>-native``,
``<run>-numpy``): the two differ by round-off (up to 1e-11 on the iCub stack). Since the C
kernels compute the pose error themselves (issue 32), ``test_tick_recorded`` holds them to
the numpy recording within the bound it states; the ``-native`` entries are kept as made. Round-off
differences grow through the QPs' active sets like that, so the recording holds to 1e-12
only where the libraries and the CPU are those it was made with (:func:`platform`, stored
in ``platform``); elsewhere ``test_tick_recorded`` skips. To record on another machine,
run this file with the tick of 75c5db1 checked out (``git checkout 75c5db1 -- ifc_spg``,
rebuild the C kernels, run, ``git checkout HEAD -- ifc_spg``, rebuild).
``python test/tick_recording.py`` rewrites the recording with the code checked out (only
when the tick is meant to change its results; the recording was made before the tick was
made faster, commit 75c5db1).
"""

from pathlib import Path
import sys

import numpy as np

TICKS = 300
SWITCH = 150
DATA = Path(__file__).resolve().parent / 'data' / 'tick_recorded.npz'

#: name: (robot, first stack, second stack); stacks: a config/tasks file or a bench stack
RUNS = {
    'lbr4_table_4_1': ('lbr4', 'table_4_1_1b_3a.yaml', 'table_4_1_1a_3b.yaml'),
    'iiwa_bench_lbr_to_collision': ('lbr_iiwa14', 'bench:lbr_stack',
                                    'table_4_1_collision_avoidance_post.yaml'),
    'icub_table_3_7': ('icub_upper_body', 'table_3_7_icub_wiping_cup_holding.yaml',
                       'bench:icub_stack'),
}


def platform():
    """What the bits of a closed loop depend on: numpy, pinocchio, DAQP, the CPU."""
    from importlib.metadata import version

    import pinocchio
    cpu = ''
    try:
        with open('/proc/cpuinfo', encoding='utf-8') as f:
            for line in f:
                if line.startswith(('model name', 'flags')):
                    key, _, value = line.partition(':')
                    value = value.strip()
                    if key.startswith('flags'):  # the SIMD sets the BLAS kernels pick
                        value = ' '.join(sorted(x for x in value.split()
                                                if x.startswith(('avx', 'fma', 'sse4'))))
                    cpu += value + '; '
                    if key.startswith('flags'):
                        break
    except OSError:
        pass
    return (f'numpy {np.__version__}, pinocchio {pinocchio.__version__}, daqp '
            f'{version("daqp")}, {sys.platform}, {cpu}')


def _stack(robot, name):
    from benchmarks import bench
    from ifc_spg import TaskStack
    from ifc_spg.offline.runner import find_config_dir
    if name.startswith('bench:'):
        return getattr(bench, name[6:])(robot)
    return TaskStack.from_file(str(find_config_dir() / 'tasks' / name))


def run(name, kernels=None):
    """The run's (q_v, qdot_v, tank energy) per tick, (TICKS, 3 n)."""
    from plants import JointImpedancePlant

    from ifc_spg import RobotModel, SetPointGenerator
    from ifc_spg.pspm import PspmConfig
    robot_name, first, second = RUNS[name]
    robot = RobotModel.from_config(robot_name)
    spg = SetPointGenerator(robot, _stack(robot, first), kernels=kernels,
                            pspm=PspmConfig(max_power=2.0))  # the stacks' power budgets
    plant = JointImpedancePlant(robot, robot.q_home, substeps=2)
    q, qd, t = plant.q, plant.qdot, 0.0
    log = np.empty((TICKS, 3 * robot.n))
    for k in range(TICKS):
        if k == SWITCH:
            spg.set_stack(_stack(robot, second))
        q_v = spg.step(q, qd, t)
        log[k] = np.concatenate([q_v, spg.qdot_v, spg.tanks.energy])
        q, qd, t = plant.step(q_v)
    return log


if __name__ == '__main__':
    here = Path(__file__).resolve().parent
    sys.path.insert(0, str(here))
    sys.path.append(str(here.parent))
    from ifc_spg import kernels
    impls = {'native': kernels.native, 'numpy': kernels.reference}
    np.savez_compressed(DATA, platform=np.array(platform()),
                        **{f'{name}-{impl}': run(name, kern) for name in RUNS
                           for impl, kern in impls.items()})
    print(f'wrote {DATA}')
