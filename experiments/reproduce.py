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
from experiments.report import write_report
from experiments.report_ch6 import REPORT_6
from ifc_spg.errors import IfcSpgError, ParameterError, did_you_mean
from ifc_spg.offline.sweep import map_unordered

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

def run_experiment(exp, out_dir, quick=False, figures=True, cache=None):
    """Run one experiment's scenarios; return ``(check, figure path or None, wall [s])``.

    Args:
        exp: An :class:`Experiment` (or the Table 5.1 entry).
        out_dir: Output directory (``runs/`` and ``figures/`` inside).
        quick: Short runs.
        figures: Draw the figure.
        cache: Dict of finished runs by (scenario, overrides, duration) shared between
            experiments (the sweeps share the base scenario).
    """
    from ifc_spg.offline.runner import load_scenario, run_scenario

    out_dir = Path(out_dir)
    wall0 = time.perf_counter()
    if exp.name in _DIRECT:
        check = _DIRECT[exp.name](out_dir, quick, figures)
        check.claims = claims.evaluate(exp.name, check.numbers, quick=quick)
        check.passed = all(c['passed'] for c in check.claims)
        fig = out_dir / 'figures' / f'{exp.name}.png'
        return check, fig if figures and fig.exists() else None, time.perf_counter() - wall0
    cache = {} if cache is None else cache
    runs = {}
    for spec in exp.runs:
        if quick and spec.full_only:
            continue
        key = (spec.scenario, json.dumps(spec.overrides, sort_keys=True), quick)
        if key in cache:
            runs[spec.label] = cache[key]
            continue
        scenario = load_scenario(_scenario_path(spec.scenario), overrides=spec.overrides)
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


def _scenario_path(name):
    from ifc_spg.offline.runner import find_config_dir

    return find_config_dir() / 'scenarios' / name


_WORKER_CACHE: dict = {}


def _experiment_in_worker(job):
    """Worker task: one scenario experiment, ``(name, out_dir, quick, figures)``.

    Its runs are cached per worker process.
    """
    name, out_dir, quick, figures = job
    exp = {e.name: e for e in ALL_EXPERIMENTS}[name]
    return run_experiment(exp, out_dir, quick=quick, figures=figures, cache=_WORKER_CACHE)


def _run_selected(selected, out_dir, quick, figures, stream, workers):
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
        jobs = [(e.name, out_dir, quick, figures) for e in order]
        for i, res in map_unordered(_experiment_in_worker, jobs, workers=workers):
            report(order[i].name, res)
    cache: dict[tuple, Run] = {}
    for exp in selected:
        if exp.name not in done:
            print(f'[reproduce] {exp.name} ...', file=stream, flush=True)
            report(exp.name, run_experiment(exp, out_dir, quick=quick, figures=figures,
                                            cache=cache))
    return done


def run_experiments(out_dir, quick=False, only=None, figures=True, stream=None, doc=None,
                    workers=None):
    """Run the selected experiments; write ``REPORT.md`` and ``results.json``; return rows.

    With ``doc`` (a directory, e.g. ``docs``) the report is also written as
    ``doc/REPRODUCTION.md`` with the figures in ``doc/figures/`` (only for a full run of
    every experiment: the committed report is a fresh full run's output). ``workers``:
    processes for the scenario experiments (default: 1 with ``quick``, else the CPU count,
    at most 4).
    """
    stream = stream or sys.stdout
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
    done = _run_selected(selected, out_dir, quick, figures, stream, workers)
    rows = []
    for exp in selected:
        check, fig, wall = done[exp.name]
        rows.append({'name': exp.name, 'table': exp.table, 'claim': exp.claim,
                     'passed': check.passed, 'summary': check.summary,
                     'numbers': check.numbers, 'claims': check.claims,
                     'figure': None if fig is None else
                     str(Path(fig).relative_to(out_dir)), 'wall_s': wall,
                     'scenarios': sorted({s.scenario for s in exp.runs})})
    (out_dir / 'results.json').write_text(json.dumps(rows, indent=1, default=float) + '\n')
    wall = time.perf_counter() - t_start
    write_report(rows, out_dir / 'REPORT.md', quick=quick, wall_s=wall)
    if doc is not None:
        doc = Path(doc)
        (doc / 'figures').mkdir(parents=True, exist_ok=True)
        for r in rows:
            if r['figure']:
                shutil.copyfile(out_dir / r['figure'], doc / r['figure'])
        write_report(rows, doc / 'REPRODUCTION.md', quick=quick, wall_s=wall)
    print(f'[reproduce] total wall {wall:.1f} s', file=stream, flush=True)
    return rows



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
                               workers=args.workers)
    except IfcSpgError as exc:
        print(f'reproduce: {exc}', file=sys.stderr)
        return 2
    failed = [r['name'] for r in rows if not r['passed']]
    cl = [c for r in rows for c in r['claims']]
    print(f'report: {Path(args.output) / "REPORT.md"}; {sum(c["passed"] for c in cl)}/'
          f'{len(cl)} claims hold, {len(rows) - len(failed)}/{len(rows)} experiments '
          'reproduced' + (f' (not: {", ".join(failed)})' if failed else ''))
    return 1 if failed and args.strict else 0


if __name__ == '__main__':
    sys.exit(main())
