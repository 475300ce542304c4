"""Benchmark of the MuJoCo bridge: real-time factor per robot/scene, and pacing lateness.

    python -m benchmarks.bridge_bench [--seconds 5] [--pacing 2]

The lockstep loop is what ``ifc-spg run`` and the node do without DDS: write q_v, step one
command period (2 ms = 2 physics steps), read the state. Real-time factor = simulated time
/ wall time. The pacing test runs the absolute-deadline pacer at 500 Hz for ``--pacing``
seconds and reports the lateness percentiles.
"""

import argparse
import json
import sys
import time

import numpy as np

from sim_bridge.pacing import DeadlinePacer
from sim_bridge.simulation import Simulation

CASES = (
    ('lbr_iiwa14', 'free'),
    ('lbr_iiwa14', 'table'),
    ('lbr_iiwa14', 'cupboard_door'),
    ('icub_upper_body', 'free'),
    ('accrea_dual_arm', 'free'),
)


def lockstep_rtf(robot, scene, seconds):
    """Return (real-time factor, bit-identical repeat) of a lockstep run of ``seconds``."""
    def run():
        sim = Simulation(robot=robot, scene=scene)
        n = round(seconds / 0.002)
        traj = np.empty((n, len(sim.joint_names)))
        t0 = time.perf_counter()
        for k in range(n):
            sim.write_command(sim.q0 + 0.1 * np.sin(2 * np.pi * 0.5 * 0.002 * k))
            sim.step(2)
            traj[k] = sim.read_state().q
        wall = time.perf_counter() - t0
        sim.close()
        return seconds / wall, traj

    rtf, a = run()
    _, b = run()
    return rtf, bool(np.array_equal(a, b))


def pacing(seconds, period=0.002):
    """Lateness statistics of the deadline pacer (no work per period)."""
    pacer = DeadlinePacer(period)
    pacer.start()
    for _ in range(int(seconds / period)):
        pacer.wait()
    return pacer.stats()


def main(argv=None):
    """Run the benchmark and print one JSON line per case."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=5.0, help='simulated time per case')
    parser.add_argument('--pacing', type=float, default=2.0, help='pacing test length [s]')
    args = parser.parse_args(argv)
    for robot, scene in CASES:
        rtf, identical = lockstep_rtf(robot, scene, args.seconds)
        print(json.dumps({'robot': robot, 'scene': scene, 'mode': 'lockstep',
                          'real_time_factor': round(rtf, 1),
                          'bit_identical_repeat': identical}))
    if args.pacing > 0:
        stats = pacing(args.pacing)
        print(json.dumps({'pacing_500Hz_us': {k: (round(v * 1e6, 1) if k in (
            'p50', 'p99', 'max') else v) for k, v in stats.items()}}))
    return 0


if __name__ == '__main__':
    sys.exit(main())
