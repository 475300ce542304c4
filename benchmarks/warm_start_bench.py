"""The cost of an explicit, restorable warm start: DAQP working sets kept by us vs by DAQP.

    python -m benchmarks.warm_start_bench [--ticks N] [--json]

:class:`~ifc_spg.cascade.daqp.DaqpCascade` keeps each level model's working set itself
(read from the multipliers after a solve, handed back as the sense flags of the next one)
so that ``spg/state`` can carry it and a replay that starts mid-run solves as the live run
did (issue 31). The baseline lets DAQP keep the working set inside the model, as the
cascade did before (:class:`InternalWarmStart`: the level solves of that version).
Both run the stacks of ``ifc-spg bench`` (LBR iiwa Table 4.1, iCub Table 3.7) in two
closed loops (joint-impedance plant) in one process, interleaved tick by tick (the order
alternating), so that machine load affects both alike. Reported per stack and variant:
the tick time (``info.tick_time``: median, p99, max [us]), the DAQP iterations per tick,
and the ratio of the median tick times (explicit / DAQP's own).
"""

import argparse
import gc
import json
import math
import sys

import numpy as np
from plants import JointImpedancePlant

from benchmarks.bench import icub_stack, lbr_stack
from ifc_spg import RobotModel, SetPointGenerator
from ifc_spg.cascade.daqp import DaqpCascade, _widen

__all__ = ['main', 'run']

STACKS = (('lbr_table_4_1', 'lbr_iiwa14', lbr_stack),
          ('icub_table_3_7', 'icub_upper_body', icub_stack))


class InternalWarmStart(DaqpCascade):
    """The baseline: DAQP keeps each model's working set (the level solves before issue 31).

    The two warm-started solves as they were (the commit before 721cf96), over the same
    workspace and models.
    """

    def _equality_level(self, lp, qdot):
        ws, i, start, end = lp.ws, lp.i, lp.start, lp.end
        n, sl = self.n, slice(start, end)
        A_i, beta, bl = ws.A[sl], ws.orig_lo[sl], ws.bl
        H, f, model = ws.level(i, start)[:3]
        self._kernels.normal_form(A_i, beta, self.rho, H, f)
        if start:
            model.update(H=H, f=f, A=ws.A_unit[:start], blower=bl[:n + start])
        else:
            model.update(H=H, f=f, blower=bl[:n])
        x, _, flag, _ = self.solve_model(model)
        if flag != 1:
            self.cold_retries += 1
            _widen(ws, qdot, start)
            model.update(blower=bl[:n + start], sense=ws.cold_sense[:n + start])
            x, _, flag, _ = self.solve_model(model)
        if flag == 1 and math.isfinite(x @ f):
            lock = end < ws.R
            return self._kernels.accept(x, bl, ws.bu, ws.A_unit[sl], ws.norm[sl], beta,
                                        ws.band[sl], ws.lo_rows[sl] if lock else None,
                                        ws.hi_rows[sl] if lock else None)
        return self._accept_slack(ws, *self._solve_with_slacks(ws, start, end), start, end)

    def _solve_slack_level(self, ws, i, start, end):
        if (ws.orig_lo[start:end] == ws.orig_hi[start:end]).any():
            return self._solve_with_slacks(ws, start, end)
        C, bu, bl, cold, model = ws.slack_level(i, start, end, self.rho)[:5]
        self._kernels.slack_setup(ws.A_unit, ws.A, start, end, ws.bl, ws.bu, ws.orig_lo,
                                  ws.orig_hi, C, bl, bu)
        model.update(A=C, blower=bl)
        x, _, flag, _ = self.solve_model(model)
        if flag != 1:
            model.update(sense=cold)
        return x, flag


def _loop(robot, make_stack, solver):
    iterations = [0]
    solve_model = solver.solve_model

    def counted(model):
        out = solve_model(model)
        iterations[0] += int(out[3].get('iterations', 0)) if isinstance(out[3], dict) else 0
        return out

    solver.solve_model = counted
    spg = SetPointGenerator(robot, make_stack(robot), solver=solver)
    plant = JointImpedancePlant(robot, robot.q_home, substeps=1)
    return spg, plant, iterations


def _stats(times, iterations, ticks):
    us = np.asarray(times) * 1e6
    return {'p50_us': float(np.median(us)), 'p99_us': float(np.percentile(us, 99)),
            'max_us': float(us.max()), 'iterations_per_tick': iterations / ticks,
            'ticks': int(us.size)}


def run(ticks=5000, warmup=200):
    """Interleaved closed loops of each stack; a list of result dicts (one per stack)."""
    results = []
    for name, robot_name, make_stack in STACKS:
        robot = RobotModel.from_config(robot_name)
        loops = {'explicit': _loop(robot, make_stack, DaqpCascade(robot.n)),
                 'daqp_internal': _loop(robot, make_stack, InternalWarmStart(robot.n))}
        state = {k: (plant.q, plant.qdot, 0.0) for k, (_, plant, _) in loops.items()}
        times = {k: [] for k in loops}
        iterations = {k: 0 for k in loops}
        gc.collect()
        gc.disable()
        try:
            for i in range(warmup + ticks):
                order = tuple(loops) if i % 2 else tuple(reversed(tuple(loops)))
                for k in order:
                    spg, plant, count = loops[k]
                    before = count[0]
                    q_v = spg.step(*state[k])
                    if i >= warmup:
                        times[k].append(spg.info.tick_time)
                        iterations[k] += count[0] - before
                    state[k] = plant.step(q_v)
        finally:
            gc.enable()
        row = {'stack': name, **{k: _stats(times[k], iterations[k], ticks) for k in loops}}
        row['ratio_p50'] = row['explicit']['p50_us'] / row['daqp_internal']['p50_us']
        results.append(row)
    return results


def main(argv=None):
    """``python -m benchmarks.warm_start_bench``."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--ticks', type=int, default=5000, help='timed ticks per loop')
    parser.add_argument('--json', action='store_true', help='print the results as JSON')
    opts = parser.parse_args(sys.argv[1:] if argv is None else argv)
    if opts.ticks < 1:
        parser.error(f'--ticks must be >= 1, got {opts.ticks}')
    results = run(opts.ticks)
    if opts.json:
        print(json.dumps(results))
        return 0
    for row in results:
        for k in ('explicit', 'daqp_internal'):
            s = row[k]
            print(f"{row['stack']:15s} {k:13s} tick p50 {s['p50_us']:7.1f} us  p99 "
                  f"{s['p99_us']:8.1f} us  max {s['max_us']:8.1f} us  DAQP iterations/tick "
                  f"{s['iterations_per_tick']:.2f}")
        print(f"{row['stack']:15s} ratio of the medians (explicit / DAQP's own) "
              f"{row['ratio_p50']:.3f}")
    return 0


if __name__ == '__main__':
    sys.exit(main())
