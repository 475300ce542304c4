"""Every shipped task stack, as shipped, in lockstep: does it run without a PSPM stall?

    python -m benchmarks.pspm_budget_bench [--minutes 10] [--only NAME ...] [--jobs 2] [-o DIR]

Issue 18's benchmark. For each stack in ``config/tasks/`` the bench runs one lockstep
scenario (:func:`ifc_spg.offline.runner.run_scenario`): the robot the stack names, with the SPG
parameters of the shipped ``config/<robot>.yaml`` (PSPM on, its ``pspm.max_power``
ceiling) and nothing else; the stack alone from t = 0, as ``task_publisher`` sends it; the
scene, its options and the start pose of the thesis scenario that runs the stack
(``config/scenarios/thesis_*.yaml``; the scenarios' own PSPM shuffling and gain sweeps are
not used). It reports per stack: the power budget the stack declares, the energy the budget
refilled into the tanks per minute, the PSPM stall episodes (0 is the pass rule: a stalled
stack is one whose empty tanks keep clipping it, see :class:`ifc_spg.pspm.StallMonitor`),
the lowest tank energy and the real-time factor. For the Table 3.2 stack it also prints the
contact-force RMS error and the circle's span per period (:func:`surface_tracking_figures`).
Exit code 1 if a stack stalled (Table 4.5 is the exception by design: its joint-5
regulator is unstable, PSPM is what stops it, so the stall is expected and reported).
"""

import argparse
from concurrent.futures import ProcessPoolExecutor
import json
import math
from pathlib import Path
import shutil
import sys
import tempfile
import time

import numpy as np
import pinocchio as pin
import yaml

from ifc_spg.model import RobotModel
from ifc_spg.offline.bag import BagReader
from ifc_spg.offline.runner import find_config_dir, run_scenario, scenario_from_dict

__all__ = ['shipped_scenario', 'surface_tracking_figures', 'run_stack', 'main']

#: Stacks whose stall is the experiment (PSPM stopping an unstable regulator).
EXPECTED_STALL = ('table_4_5_stability',)
#: Table 3.2's pass rule (issue 18), from the stack's activation: contact-force RMS error
#: after SETTLE_S, circle span (the smaller of its x and y extent) in every full period.
SURFACE_FORCE_N = -8.0
SURFACE_SETTLE_S = 5.0
SURFACE_MAX_RMS_N = 1.0
SURFACE_MIN_SPAN_M = 0.09


def _thesis_scenario(stack_file):
    """The thesis scenario running ``stack_file`` (first with PSPM on), or None."""
    for path in sorted((find_config_dir() / 'scenarios').glob('thesis_*.yaml')):
        doc = yaml.safe_load(path.read_text(encoding='utf8'))
        files = [e.get('file') for e in doc.get('stacks') or []]
        pspm = (doc.get('spg') or {}).get('pspm', True)
        on = pspm if isinstance(pspm, bool) else pspm.get('enabled', True)
        if stack_file in files and on:
            return doc
    return None


# stacks no thesis scenario runs from its file: the scene of the experiment
_SCENES = {'table_3_4_circle_drawing.yaml': {'scene': 'table', 'scene_options': {'gap': 0.005}},
           'table_5_1_constrained_manipulation.yaml': {'scene': 'drawer_vertical'}}


def shipped_scenario(stack_file, seconds, robot=None, scene=None, scene_options=None,
                     power=None):
    """The scenario dict of ``stack_file`` (a name in ``config/tasks/``) as shipped.

    Args:
        stack_file: File name in ``config/tasks/``.
        seconds: Duration [s].
        robot: Override the robot (default: the stack's ``robot``).
        scene: Override the thesis scenario's scene.
        scene_options: Override the scene's options.
        power: Override the stack's power_budget and the ceiling [W] (to measure a need).
    """
    tasks_dir = find_config_dir() / 'tasks'
    stack = yaml.safe_load((tasks_dir / stack_file).read_text(encoding='utf8'))
    thesis = _thesis_scenario(stack_file) or dict(_SCENES.get(stack_file, {}))
    robot = robot or stack.get('robot') or thesis.get('robot') or 'lbr_iiwa14'
    data = {'name': Path(stack_file).stem, 'robot': robot, 'dt': 0.002, 'timestep': 0.001,
            'scene': scene or thesis.get('scene', 'free'),
            'scene_options': scene_options if scene_options is not None else
            thesis.get('scene_options') or {},
            'duration': float(seconds), 'spg': {'params_file': f'{robot}.yaml'},
            'stacks': [{'at': 0.0, 'file': stack_file} if power is None else
                       {'at': 0.0, 'stack': dict(stack, power_budget=float(power))}],
            'progress': 0,
            'metrics': ['tank_energy_min', 'max_contact_force', 'limit_violations',
                        'tick_time', 'missed_ticks']}
    for key in ('q0', 'q0_deg'):
        if thesis.get(key) is not None:
            data[key] = thesis[key]
    if power is not None:
        data['spg']['pspm.max_power'] = float(power)
    sim = {k: v for k, v in (thesis.get('sim') or {}).items()
           if k not in ('stiffness', 'damping')}
    if sim:
        data['sim'] = sim
    return data


def surface_tracking_figures(bag, robot, *, period, start=0.0, settle=SURFACE_SETTLE_S,
                             target=SURFACE_FORCE_N, frame='tool'):
    """Contact-force RMS error and circle spans of a surface-tracking run, from its bag.

    Args:
        bag: Bag directory of the run.
        robot: The :class:`~ifc_spg.model.RobotModel` (forward kinematics of the tool).
        period: Circle period [s].
        start: Time [s] the stack became active.
        settle: Seconds after ``start`` before the force error counts.
        target: Force the tool exerts along base z [N] (-8: pressing down with 8 N).
        frame: Chain id of the tool.

    Returns:
        ``{'force_rms_n', 'force_mean_n', 'spans_m': [per full period], 'min_span_m'}``;
        a period's span is the smaller of the measured tool's x and y extent.
    """
    fid = robot.frame_id(frame)
    data = robot.create_data()
    t_js, xy, t_f, fz = [], [], [], []
    with BagReader(bag) as reader:
        for topic, t, msg in reader.messages(['/joint_states', '/sim/contact_wrench']):
            ts = t * 1e-9 - start
            if topic == '/joint_states':
                pin.framesForwardKinematics(robot.model, data, np.asarray(msg.position))
                t_js.append(ts)
                xy.append(data.oMf[fid].translation[:2].copy())
            else:
                t_f.append(ts)
                fz.append(-msg.wrench.force.z)  # the force the robot exerts (base z)
    t_js, xy, t_f, fz = (np.asarray(x) for x in (t_js, xy, t_f, fz))
    err = fz[t_f >= settle] - target
    spans = []
    for k in range(int(math.floor(t_js[-1] / period))):
        sel = (t_js >= k * period) & (t_js < (k + 1) * period)
        spans.append(float(np.min(np.ptp(xy[sel], axis=0))))
    return {'force_rms_n': float(np.sqrt(np.mean(err ** 2))), 'force_mean_n':
            float(np.mean(fz[t_f >= settle])), 'spans_m': spans,
            'min_span_m': min(spans) if spans else None}


def run_stack(stack_file, seconds, out_dir=None, power=None):
    """Run one shipped stack; return its row (dict). The bag is deleted unless ``out_dir``.

    ``net_j_per_min`` is the energy the SPG spent from the tanks beyond what the IFC damper
    returned, per minute: initial tank energy + refill - final tank energy.
    """
    data = shipped_scenario(stack_file, seconds, power=power)
    scenario = scenario_from_dict(data, where=f'bench:{stack_file}',
                                  base=find_config_dir() / 'tasks')
    tmp = Path(tempfile.mkdtemp(prefix='pspm_bench_')) if out_dir is None else \
        Path(out_dir) / Path(stack_file).stem
    try:
        result = run_scenario(scenario, tmp, quiet=True)
        m = result.metrics
        pspm = m.get('pspm') or {}
        stack = yaml.safe_load((find_config_dir() / 'tasks' / stack_file).read_text())
        row = {'stack': Path(stack_file).stem, 'robot': scenario.robot,
               'scene': scenario.scene, 'minutes': m['duration_s'] / 60.0,
               'power_budget_w': pspm.get('power_budget_w', 0.0),
               'max_power_w': pspm.get('max_power_w'),
               'refilled_j_per_min': pspm.get('refilled_per_minute_j'),
               'net_j_per_min': None if not pspm else
               (pspm['tank_energy_start_j'] + pspm['refilled_j'] - pspm['tank_energy_end_j']) *
               60.0 / m['duration_s'],
               'stalls': pspm.get('stalls'), 'stall': pspm.get('last_stall_message'),
               'tank_energy_min_j': m.get('tank_energy_min_j'),
               'limit_violations': m.get('limit_violations'),
               'max_contact_force_n': m.get('max_contact_force_n'),
               'real_time_factor': m.get('real_time_factor')}
        if stack_file.startswith('table_3_2'):
            circle = next(t for t in stack['tasks'] if t['name'] == 'circle')
            row['surface'] = surface_tracking_figures(
                result.bag, RobotModel.from_config(scenario.robot),
                period=1.0 / circle['equal']['frequency'])
            row['surface']['spans_m'] = [round(s, 4) for s in row['surface']['spans_m']]
        return row
    finally:
        if out_dir is None:
            shutil.rmtree(tmp, ignore_errors=True)


def _row_text(r):
    refill = r['refilled_j_per_min']
    text = (f"{r['stack']:<38} {r['robot']:<16} {r['power_budget_w']:>6g} W "
            f"refill {'-' if refill is None else f'{refill:7.2f}'} J/min, net use "
            f"{r['net_j_per_min'] or 0.0:7.2f} J/min  stalls {r['stalls']}  "
            f"tank min {r['tank_energy_min_j'] or 0.0:.3f} J  rtf {r['real_time_factor']:.2f}")
    if 'surface' in r:
        s = r['surface']
        text += (f"\n    Table 3.2: force RMS error {s['force_rms_n']:.3f} N after "
                 f"{SURFACE_SETTLE_S:g} s (mean {s['force_mean_n']:.2f} N), circle span "
                 f"min {s['min_span_m'] * 100:.2f} cm over {len(s['spans_m'])} periods")
    if r['stalls']:
        text += f"\n    {r['stall']}"
    return text


def main(argv=None):
    """Run the benchmark; exit code 1 if an unexpected stack stalled."""
    parser = argparse.ArgumentParser(prog='python -m benchmarks.pspm_budget_bench',
                                     description=__doc__.split('\n')[0])
    parser.add_argument('--minutes', type=float, default=10.0, help='simulated minutes')
    parser.add_argument('--only', nargs='*', default=None, help='stack names (file stems)')
    parser.add_argument('--jobs', type=int, default=1, help='parallel processes')
    parser.add_argument('-o', '--output', default=None, help='keep bags and rows here')
    parser.add_argument('--json', default=None, help='write the rows to this JSON file')
    parser.add_argument('--power', type=float, default=None,
                        help="measure: every stack's power_budget and the ceiling set to this "
                        '[W] instead of the shipped values')
    opts = parser.parse_args(sys.argv[1:] if argv is None else argv)
    files = sorted(p.name for p in (find_config_dir() / 'tasks').glob('*.yaml'))
    if opts.only:
        files = [f for f in files if Path(f).stem in opts.only]
    seconds = opts.minutes * 60.0
    wall = time.perf_counter()
    print(f'{len(files)} stacks, {opts.minutes:g} simulated minutes each, lockstep, shipped '
          'parameters', flush=True)
    rows = []
    with ProcessPoolExecutor(max_workers=max(1, opts.jobs)) as pool:
        futures = [pool.submit(run_stack, f, seconds, opts.output, opts.power)
                   for f in files]
        for fut in futures:
            row = fut.result()
            rows.append(row)
            print(_row_text(row), flush=True)
    bad = [r['stack'] for r in rows if r['stalls'] and r['stack'] not in EXPECTED_STALL]
    print(f'wall {time.perf_counter() - wall:.0f} s; stalled: {", ".join(bad) or "none"}'
          f' (expected: {", ".join(EXPECTED_STALL)})')
    if opts.json:
        Path(opts.json).write_text(json.dumps(rows, indent=1) + '\n')
    return 1 if bad else 0


if __name__ == '__main__':
    sys.exit(main())
