"""Reproduce the thesis experiments in simulation: ``python -m experiments.reproduce``.

    python -m experiments.reproduce [--quick] [-o DIR] [--only NAME ...] [--list] [--doc docs]

Each experiment runs one or more scenarios of ``config/scenarios/thesis_*.yaml`` with the
offline lockstep runner (:func:`ifc_spg.offline.runner.run_scenario`; bags and ``metrics.json`` in
``DIR/runs/<run>/``), computes the numbers its claims rest on, evaluates the pass rules of
:mod:`experiments.claims` (one per thesis claim, fixed before the runs), draws a figure in
the style of the thesis figure (``DIR/figures/<name>.png``) and writes ``DIR/REPORT.md``
(per claim: source, thesis value, ours, rule, verdict, what was changed after a result) and
``DIR/results.json``. ``--quick`` runs shortened versions (what the test suite runs) and
evaluates the claims that do not need the full run. ``--doc docs`` writes the repository's
``docs/REPRODUCTION.md`` (full runs only).

``--fri-delay N`` runs every simulation on an LBR's FRI emulation with a loop delay of N FRI
periods (``sim.fri_delay``; the thesis' robots had one, a real client answers one period
later: ``N = 1``), where the experiment's scenario does not set its own: the scenario
experiments of Chs. 3/4 and the Sec. 5.4.3 runs (Figs. 5.11-5.13). The iCub and ACCREA runs,
Table 5.1 (its own worker processes) and report Ch. 6 (no simulation) run as without it;
the report says which ran delayed. With ``--doc`` it is written as
``REPRODUCTION_FRI_DELAY.md``.

Sweeps (Figs. 3.14/3.15) are built from ``thesis_3_2_surface_tracking.yaml`` by scenario
overrides: the joint stiffness K (``sim: {stiffness, damping}``; D scaled with sqrt(K) for a
constant damping ratio) and the circle frequency (a copy of the scenario's Table 3.2
stack, the thesis' static force model).
Table 5.1 reuses :mod:`ifc_spg.offline.constrained_evaluate`; report Ch. 6 evaluates
:func:`ifc_spg.dynamics.scenarios.report_problems` (no simulation).

The experiments are in the module of their thesis chapter (:mod:`experiments.ch3`,
:mod:`experiments.ch4`, :mod:`experiments.ch5`, :mod:`experiments.report_ch6`); the run
records in :mod:`experiments.harness`, the report writer in :mod:`experiments.report`.

The exit status is 0 when every experiment ran (whether its claims hold or not) and 2 on an
error; ``--strict`` makes a failing claim exit 1.
"""

import argparse
import dataclasses
import json
import os
from pathlib import Path
import shutil
import sys
import time

from experiments import ch5, claims, report_ch6
from experiments.ch3 import CH3_EXPERIMENTS
from experiments.ch4 import CH4_EXPERIMENTS
from experiments.ch5 import CH5_EXPERIMENTS
from experiments.harness import Check, Experiment, Run, RunSpec
from experiments.report import FRI_PREAMBLE, PREAMBLE, write_report
from experiments.report_ch6 import REPORT_6
from ifc_spg.errors import IfcSpgError, ParameterError, did_you_mean
from ifc_spg.offline.sweep import map_unordered
from sim_bridge.interface import check_fri_delay

__all__ = ['ALL_EXPERIMENTS', 'EXPERIMENTS', 'Check', 'Experiment', 'RunSpec', 'main',
           'run_experiment', 'run_experiments', 'write_report']

#: The scenario experiments (Ch. 3 and 4), in report order.
EXPERIMENTS = CH3_EXPERIMENTS + CH4_EXPERIMENTS
_DIRECT = {**ch5.DIRECT, **report_ch6.DIRECT}
#: Every experiment, in report order.
ALL_EXPERIMENTS = EXPERIMENTS + CH5_EXPERIMENTS + (REPORT_6,)


def experiment_names():
    """All experiment names (``--only`` choices)."""
    return tuple(e.name for e in ALL_EXPERIMENTS)


# -- running -------------------------------------------------------------------------------

def run_experiment(exp, out_dir, quick=False, figures=True, cache=None, fri_delay=0):
    """Run one experiment's scenarios; return ``(check, figure path or None, wall [s])``.

    Args:
        exp: An :class:`Experiment` (or the Table 5.1 entry).
        out_dir: Output directory (``runs/`` and ``figures/`` inside).
        quick: Short runs.
        figures: Draw the figure.
        cache: Dict of finished runs by (scenario, overrides, duration) shared between
            experiments (the sweeps share the base scenario).
        fri_delay: FRI loop delay [periods] for the runs on an LBR's FRI emulation whose
            scenario sets none (see the module docstring).
    """
    from ifc_spg.offline.runner import load_scenario, run_scenario

    out_dir = Path(out_dir)
    wall0 = time.perf_counter()
    if exp.name in _DIRECT:
        ch5.FRI_DELAY = fri_delay
        try:
            check = _DIRECT[exp.name](out_dir, quick, figures)
        finally:
            ch5.FRI_DELAY = 0
        check.claims = claims.evaluate(exp.name, check.numbers, quick=quick)
        check.passed = all(c['passed'] for c in check.claims)
        fig = out_dir / 'figures' / f'{exp.name}.png'
        return check, fig if figures and fig.exists() else None, time.perf_counter() - wall0
    cache = {} if cache is None else cache
    runs = {}
    for spec in exp.runs:
        if quick and spec.full_only:
            continue
        key = (spec.scenario, json.dumps(spec.overrides, sort_keys=True), quick, fri_delay)
        if key in cache:
            runs[spec.label] = cache[key]
            continue
        scenario = load_scenario(_scenario_path(spec.scenario), overrides=spec.overrides)
        if fri_delay and 'fri_delay' not in scenario.sim and _on_fri(scenario):
            scenario = dataclasses.replace(scenario, sim={**scenario.sim,
                                                          'fri_delay': fri_delay})
        duration = spec.quick if quick else spec.duration
        run_dir = out_dir / 'runs' / f'{exp.name}_{spec.label}'
        if run_dir.exists():
            shutil.rmtree(run_dir)
        result = run_scenario(scenario, run_dir, duration=duration, quiet=True)
        run = Run(spec, result)
        run.scenario = scenario
        run.pushes = [{'at': p.at, 'duration': p.duration} for p in scenario.pushes]
        runs[spec.label] = run
        cache[key] = run
    check = exp.check(runs, quick)
    check.claims = claims.evaluate(exp.name, check.numbers, quick=quick)
    check.passed = all(c['passed'] for c in check.claims)
    fig = None
    if figures and exp.figure is not None:
        fig_dir = out_dir / 'figures'
        fig_dir.mkdir(parents=True, exist_ok=True)
        fig = fig_dir / f'{exp.name}.png'
        exp.figure(runs, quick, fig)
    return check, fig, time.perf_counter() - wall0


def _on_fri(scenario):
    """Whether ``scenario`` runs on the LBR FRI emulation (``sim.fri_delay`` applies)."""
    from ifc_spg.model import RobotModel
    from sim_bridge.simulation import default_interface

    return (scenario.interface or
            default_interface(RobotModel.from_config(scenario.robot))) == 'lbr_fri'


def _delays(exp):
    """Whether ``--fri-delay`` reaches runs of ``exp`` (see the module docstring)."""
    from ifc_spg.offline.runner import load_scenario

    if exp.name in _DIRECT:
        return exp.name in ch5.FRI_DELAYED
    return any('fri_delay' not in sc.sim and _on_fri(sc) for sc in (
        load_scenario(_scenario_path(spec.scenario), overrides=spec.overrides)
        for spec in exp.runs))


def _scenario_path(name):
    from ifc_spg.offline.runner import find_config_dir

    return find_config_dir() / 'scenarios' / name


_WORKER_CACHE: dict = {}


def _experiment_in_worker(job):
    """Worker task: one scenario experiment, ``(name, out_dir, quick, figures, fri_delay)``.

    Its runs are cached per worker process.
    """
    name, out_dir, quick, figures, fri_delay = job
    exp = {e.name: e for e in ALL_EXPERIMENTS}[name]
    return run_experiment(exp, out_dir, quick=quick, figures=figures, cache=_WORKER_CACHE,
                          fri_delay=fri_delay)


def _run_selected(selected, out_dir, quick, figures, stream, workers, fri_delay=0):
    """Run ``selected``; return {name: (check, figure, wall)}.

    The scenario experiments go to a local Dask cluster of ``workers`` worker processes
    (:func:`ifc_spg.offline.sweep.map_unordered`, longest first) when
    ``workers`` > 1; the others (Table 5.1, Ch. 5, report Ch. 6) run here afterwards and
    use processes of their own. Every run is deterministic: the results do not depend on
    ``workers``.
    """
    done = {}

    def report(name, res):
        done[name] = res
        check, _, wall = res
        print(f"[reproduce] {name}: {'PASS' if check.passed else 'FAIL'} ({wall:.1f} s) "
              f'{check.summary}', file=stream, flush=True)

    pooled = [e for e in selected if e.name not in _DIRECT] if workers > 1 else []
    if len(pooled) > 1:
        order = sorted(pooled, key=lambda e: -sum(r.duration or 10.0 for r in e.runs))
        print(f'[reproduce] {len(pooled)} scenario experiments in {workers} processes '
              '(a local Dask cluster) ...', file=stream, flush=True)
        jobs = [(e.name, out_dir, quick, figures, fri_delay) for e in order]
        for i, res in map_unordered(_experiment_in_worker, jobs, workers=workers):
            report(order[i].name, res)
    cache: dict[tuple, Run] = {}
    for exp in selected:
        if exp.name not in done:
            print(f'[reproduce] {exp.name} ...', file=stream, flush=True)
            report(exp.name, run_experiment(exp, out_dir, quick=quick, figures=figures,
                                            cache=cache, fri_delay=fri_delay))
    return done


def run_experiments(out_dir, quick=False, only=None, figures=True, stream=None, doc=None,
                    workers=None, fri_delay=0):
    """Run the selected experiments; write ``REPORT.md`` and ``results.json``; return rows.

    With ``doc`` (a directory, e.g. ``docs``) the report is also written as
    ``doc/REPRODUCTION.md`` with the figures in ``doc/figures/`` (only for a full run of
    every experiment: the committed report is a fresh full run's output). ``workers``:
    processes for the scenario experiments (default: 1 with ``quick``, else the CPU count,
    at most 4). ``fri_delay``: see the module docstring (the report then says which
    experiments ran delayed; ``doc`` gets ``REPRODUCTION_FRI_DELAY.md``).
    """
    stream = stream or sys.stdout
    fri_delay = check_fri_delay(fri_delay)
    t_start = time.perf_counter()
    if doc is not None and (quick or only):
        raise ParameterError('--doc writes docs/REPRODUCTION.md from a full run of every '
                             'experiment (without --quick and --only)')
    names = experiment_names()
    for name in only or ():
        if name not in names:
            raise ParameterError(f"unknown experiment '{name}'{did_you_mean(name, names)}; "
                                 f"experiments: {', '.join(names)}")
    if workers is None:
        workers = 1 if quick else max(1, min(4, os.cpu_count() or 1))
    selected = [e for e in ALL_EXPERIMENTS if not only or e.name in only]
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    done = _run_selected(selected, out_dir, quick, figures, stream, workers, fri_delay)
    rows = []
    for exp in selected:
        check, fig, wall = done[exp.name]
        rows.append({'name': exp.name, 'table': exp.table, 'claim': exp.claim,
                     'ours': exp.ours, 'passed': check.passed, 'summary': check.summary,
                     'numbers': check.numbers, 'claims': check.claims,
                     'figure': None if fig is None else
                     str(Path(fig).relative_to(out_dir)), 'wall_s': wall,
                     'scenarios': sorted({s.scenario for s in exp.runs}),
                     'fri_delay': fri_delay if fri_delay and _delays(exp) else 0})
    (out_dir / 'results.json').write_text(json.dumps(rows, indent=1, default=float) + '\n')
    wall = time.perf_counter() - t_start
    _write_reports(rows, out_dir, doc, quick, wall, fri_delay)
    print(f'[reproduce] total wall {wall:.1f} s', file=stream, flush=True)
    return rows



def _write_reports(rows, out_dir, doc, quick, wall, fri_delay):
    """``REPORT.md``, and with ``doc`` the repository's report (see :func:`run_experiments`)."""
    preamble = None
    if fri_delay:
        names = {flag: ', '.join(r['name'] for r in rows if bool(r['fri_delay']) == flag)
                 or 'none' for flag in (True, False)}
        preamble = (PREAMBLE.format(version=claims.VERSION) + '\n\n' + FRI_PREAMBLE.format(
            n=fri_delay, ms=2 * fri_delay, delayed=names[True], undelayed=names[False]))
    write_report(rows, out_dir / 'REPORT.md', quick=quick, wall_s=wall, preamble=preamble)
    if doc is None:
        return
    doc = Path(doc)
    if fri_delay:  # the committed figures are the undelayed run's
        write_report([{**r, 'figure': None} for r in rows], doc / 'REPRODUCTION_FRI_DELAY.md',
                     quick=quick, wall_s=wall, preamble=preamble)
        return
    (doc / 'figures').mkdir(parents=True, exist_ok=True)
    for r in rows:
        if r['figure']:
            shutil.copyfile(out_dir / r['figure'], doc / r['figure'])
    write_report(rows, doc / 'REPRODUCTION.md', quick=quick, wall_s=wall)


def main(argv=None):
    """Command line entry (see the module docstring)."""
    ap = argparse.ArgumentParser(prog='python -m experiments.reproduce',
                                 description=__doc__.splitlines()[0])
    ap.add_argument('-o', '--output', default='out/reproduce', help='output directory')
    ap.add_argument('--quick', action='store_true', help='short runs (what the tests run)')
    ap.add_argument('--only', nargs='+', default=None, metavar='NAME',
                    help='experiments to run (see --list)')
    ap.add_argument('--list', action='store_true', help='list the experiments and exit')
    ap.add_argument('--no-figures', action='store_true', help='skip the figures')
    ap.add_argument('--strict', action='store_true', help='exit 1 if a claim fails')
    ap.add_argument('--workers', type=int, default=None, metavar='N',
                    help='processes for the scenario experiments (default: 1 with --quick, '
                    'else the CPU count, at most 4; the results do not depend on it)')
    ap.add_argument('--fri-delay', type=int, default=0, metavar='N',
                    help='run the simulations on an LBR FRI emulation with a loop delay of N '
                    'FRI periods (1: a client that answers one period later, as a real one); '
                    'see the module docstring for which runs')
    ap.add_argument('--doc', default=None, metavar='DIR',
                    help='also write DIR/REPRODUCTION.md and DIR/figures/ (full runs only; '
                    'the repository report: --doc docs)')
    args = ap.parse_args(argv)
    if args.list:
        for e in ALL_EXPERIMENTS:
            print(f'{e.name:12s} {e.table:10s} {e.claim}')
        return 0
    try:
        rows = run_experiments(args.output, quick=args.quick, only=args.only,
                               figures=not args.no_figures, doc=args.doc,
                               workers=args.workers, fri_delay=args.fri_delay)
    except IfcSpgError as exc:
        print(f'reproduce: {exc}', file=sys.stderr)
        return 2
    failed = [r['name'] for r in rows if not r['passed']]
    cl = [c for r in rows for c in r['claims']]
    thesis = [r for r in rows if not r.get('ours')]
    print(f'report: {Path(args.output) / "REPORT.md"}; {sum(c["passed"] for c in cl)}/'
          f'{len(cl)} claims hold, {sum(r["passed"] for r in thesis)}/{len(thesis)} thesis '
          f'experiments reproduced' + (f' (not: {", ".join(failed)})' if failed else ''))
    return 1 if failed and args.strict else 0


if __name__ == '__main__':
    sys.exit(main())
