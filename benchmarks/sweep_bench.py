"""Sweep throughput: N short lockstep runs serially vs on a local Dask cluster.

    python -m benchmarks.sweep_bench [--runs 40] [--duration 0.3] [--workers 2]
                                        [--repeat 1] [--json FILE]

The sweep: ``free_push`` (LBR iiwa 14 holding its tool pose against a push) with
``--duration`` seconds of simulated time, the joint stiffness drawn at random (``--runs``
samples, so every run is a distinct point). Both engines run the same points in this
process's invocation, alternating ``--repeat`` times (serial first), each into a fresh
directory:

- serial: ``run_sweep(workers=1)``, in this process;
- dask: ``run_sweep`` on a ``LocalCluster`` of ``--workers`` worker processes (one thread
  each, 127.0.0.1), started once before the first repeat (its start-up time is reported on
  its own) and kept for the repeats.

Before timing, this process and every worker run a 0.02 s scenario once (imports, model
loading), so both engines are measured warm.

Reported: throughput [runs/min] per engine and their ratio; the runs' own wall time
(median, p99, max [s], measured inside run_point); Dask's overhead per run, three ways:
(workers x sweep wall - sum of run walls) / runs, i.e. the worker time not spent running;
the CPU time of this process (client and scheduler) per run; the round trip of a no-op
task (4 x 50 through ``client.map``, median [ms]); and whether the two tables are
identical row by row (all columns but wall_time_s). The load average before and after
says how busy the (possibly shared) machine was.
"""

import argparse
import csv
import json
import os
from pathlib import Path
import statistics
import sys
import tempfile
import time

import numpy as np

from ifc_spg.offline.sweep import read_records, run_sweep
from ifc_spg.offline.sweep_spec import load_sweep

__all__ = ['main', 'run_benchmark']

_SWEEP = """\
name: bench_free_push
scenario: free_push.yaml
set: {{duration: {duration}, progress: 0, pushes.0.at: 0.05, pushes.0.duration: 0.1}}
axes:
  sim.stiffness: {{uniform: [150.0, 800.0]}}
samples: {runs}
seed: 1
metrics: [task_error_rms.physical, tank_energy_min_j]
"""


def _noop(x):
    return x


def _warm_up():
    """Import and run a 0.02 s scenario once, so the timed runs start warm."""
    from ifc_spg.offline.runner import load_scenario, run_scenario

    with tempfile.TemporaryDirectory() as d:
        run_scenario(load_scenario('free_push.yaml', {'duration': 0.02, 'progress': 0}), d,
                     quiet=True)


def _table(out_dir):
    with open(Path(out_dir) / 'results.csv', newline='') as f:
        return [{k: v for k, v in r.items() if k != 'wall_time_s'} for r in csv.DictReader(f)]


def _run_walls(spec, out_dir):
    return [r['wall_time_s'] for r in read_records(out_dir, spec.points())]


def _stats(x):
    x = np.asarray(x, float)
    return {'median': float(np.median(x)), 'p99': float(np.percentile(x, 99)),
            'max': float(x.max())}


def run_benchmark(runs=40, duration=0.3, workers=2, repeat=1):
    """Run the benchmark; a dict of the results (see the module docstring)."""
    import distributed

    tmp = Path(tempfile.mkdtemp(prefix='ifc_spg_sweep_bench_'))
    path = tmp / 'bench.yaml'
    path.write_text(_SWEEP.format(duration=duration, runs=runs))
    spec = load_sweep(path)
    out = {'runs': runs, 'duration_s': duration, 'workers': workers,
           'cpu_count': os.cpu_count(), 'loadavg_before': os.getloadavg(), 'repeats': []}
    t0 = time.perf_counter()
    cluster = distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                       host='127.0.0.1', dashboard_address=None)
    client = distributed.Client(cluster)
    client.run(_noop, 0)  # the workers are up
    out['cluster_start_s'] = time.perf_counter() - t0
    client.run(_warm_up)
    _warm_up()
    try:
        for k in range(repeat):
            rep = {}
            for engine in ('serial', 'dask'):
                d = tmp / f'{engine}{k}'
                t, cpu = time.perf_counter(), time.process_time()
                if engine == 'serial':
                    run_sweep(spec, d, workers=1, stream=None)
                else:
                    run_sweep(spec, d, client=client, stream=None)
                wall = time.perf_counter() - t
                cpu = time.process_time() - cpu
                walls = _run_walls(spec, d)
                n_workers = 1 if engine == 'serial' else workers
                rep[engine] = {'wall_s': wall, 'runs_per_min': 60.0 * runs / wall,
                               'run_wall_s': _stats(walls),
                               'overhead_per_run_s': (n_workers * wall - sum(walls)) / runs,
                               'this_process_cpu_per_run_s': cpu / runs}
            rep['ratio'] = rep['dask']['runs_per_min'] / rep['serial']['runs_per_min']
            rep['identical_rows'] = _table(tmp / f'serial{k}') == _table(tmp / f'dask{k}')
            out['repeats'].append(rep)
        rt = []
        for _ in range(4):
            t = time.perf_counter()
            client.gather(client.map(_noop, range(50), pure=False))
            rt.append((time.perf_counter() - t) / 50)
        out['noop_task_ms'] = 1e3 * statistics.median(rt)
    finally:
        client.close()
        cluster.close()
    out['loadavg_after'] = os.getloadavg()
    return out


def format_report(res):
    """The results as text."""
    lines = [f"sweep throughput: {res['runs']} lockstep runs of free_push, "
             f"{res['duration_s']:g} s simulated each; {res['workers']} Dask workers on "
             f"{res['cpu_count']} cores; load average before "
             f"{' '.join(f'{x:.2f}' for x in res['loadavg_before'])}, after "
             f"{' '.join(f'{x:.2f}' for x in res['loadavg_after'])}",
             f"LocalCluster start-up: {res['cluster_start_s']:.2f} s (not in the walls below)"]
    for k, rep in enumerate(res['repeats']):
        for engine in ('serial', 'dask'):
            r = rep[engine]
            w = r['run_wall_s']
            lines.append(f"  [{k}] {engine:<6} {r['wall_s']:6.2f} s  {r['runs_per_min']:6.1f} "
                         f"runs/min  run wall median {w['median']:.3f} p99 {w['p99']:.3f} max "
                         f"{w['max']:.3f} s  overhead/run {1e3 * r['overhead_per_run_s']:.1f} ms  "
                         f"this process CPU/run {1e3 * r['this_process_cpu_per_run_s']:.1f} ms")
        lines.append(f"  [{k}] dask/serial throughput ratio {rep['ratio']:.2f}; rows identical: "
                     f"{rep['identical_rows']}")
    lines.append(f"Dask no-op task round trip (client.map, median of 4 x 50): "
                 f"{res['noop_task_ms']:.2f} ms")
    return '\n'.join(lines)


def main(argv=None):
    """Entry point: run and print the benchmark."""
    p = argparse.ArgumentParser(prog='python -m benchmarks.sweep_bench',
                                description=__doc__.split('\n')[0])
    p.add_argument('--runs', type=int, default=40, help='runs per engine (default 40)')
    p.add_argument('--duration', type=float, default=0.3,
                   help='simulated seconds per run (default 0.3)')
    p.add_argument('--workers', type=int, default=2, help='Dask worker processes (default 2)')
    p.add_argument('--repeat', type=int, default=1, help='serial/dask alternations')
    p.add_argument('--json', help='also write the results to this JSON file')
    args = p.parse_args(argv)
    if args.runs < 1 or args.workers < 1 or args.repeat < 1 or not args.duration > 0:
        p.error('--runs, --workers, --repeat must be >= 1 and --duration > 0')
    res = run_benchmark(args.runs, args.duration, args.workers, args.repeat)
    print(format_report(res))
    if args.json:
        Path(args.json).write_text(json.dumps(res, indent=1) + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
