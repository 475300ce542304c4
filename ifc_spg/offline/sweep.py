"""Run a sweep's points with the lockstep runner: serially, or on Dask (``ifc-spg sweep``).

Engines (:func:`run_sweep`):

- ``workers=1``: in this process, one point after the other;
- default: a local Dask cluster (``distributed.LocalCluster``: one worker process per
  core, one thread each, bound to 127.0.0.1, no dashboard);
- ``scheduler='tcp://HOST:8786'``: an existing Dask scheduler and its workers (started by
  hand with ``dask scheduler`` / ``dask worker``, or by dask-jobqueue on Slurm/PBS).

Each point is one call of :func:`run_point` (the worker's side): the point's scenario
(complete, stack files read in) is validated and run by
:func:`~ifc_spg.offline.runner.run_scenario`; an exception becomes the record's ``error``,
not the end of the sweep. The records are written by this process, one JSON file per
point, ``DIR/runs/KEY.json`` (KEY: :func:`~ifc_spg.offline.sweep_spec.point_key`, a hash of
the point's scenario, sample index and the code version); ``resume=True`` skips points
whose file exists.
``DIR/results.csv`` has one row per point (:data:`FIXED_COLUMNS`, then the axes, then the
metrics). The rows do not depend on the engine: a run is deterministic, so only
``wall_time_s`` (and timing metrics such as ``tick_time_ms``) differ between runs.

When a Dask worker dies while running a point, the scheduler runs the point again on
another worker (``distributed.scheduler.allowed-failures`` times, default 3); a point that
killed that many workers is a row with status ``error``.
"""

import contextlib
import csv
import json
import math
import os
from pathlib import Path
import shutil
import sys
import tempfile
import time

from ifc_spg.errors import ParameterError
from ifc_spg.offline.sweep_spec import code_version

__all__ = ['FIXED_COLUMNS', 'map_unordered', 'metric_value', 'read_records', 'run_point',
           'run_sweep', 'write_table']

FIXED_COLUMNS = ('point', 'key', 'status', 'error', 'seed', 'sample', 'wall_time_s')
RESULTS = 'results.csv'


def run_point(task):
    """Run one point (on a worker or in this process); its record (a plain dict).

    Args:
        task: ``{'key', 'index', 'scenario' (mapping), 'where', 'base_dir', 'bag_dir',
            'code_version'}``; ``bag_dir`` None: the bag goes to a temporary directory,
            removed afterwards; a worker whose :func:`code_version` differs from
            ``code_version`` runs nothing and returns an error record.
    """
    from ifc_spg.offline.runner import run_scenario, scenario_from_dict

    t0 = time.perf_counter()
    record = {'key': task['key'], 'point': task['index'], 'status': 'ok', 'error': None,
              'metrics': None}
    tmp = None
    try:
        here = code_version()
        if task.get('code_version') not in (None, here):
            raise ParameterError(f'this worker runs ifc_spg {here}, the sweep '
                                 f"{task['code_version']}; give every worker the same ifc_spg "
                                 '(checkout and commit)')
        scenario = scenario_from_dict(task['scenario'], where=task['where'],
                                      base=Path(task['base_dir']))
        out = task['bag_dir'] or tempfile.mkdtemp(prefix='ifc_spg_sweep_')
        tmp = None if task['bag_dir'] else out
        if task['bag_dir'] and os.path.exists(os.path.join(out, 'bag')):
            shutil.rmtree(os.path.join(out, 'bag'))  # a run cut short before: run it again
        record['metrics'] = run_scenario(scenario, out, quiet=True).metrics
    except Exception as exc:  # noqa: BLE001 - a failing run is a row with its error
        record['status'] = 'error'
        record['error'] = f'{type(exc).__name__}: {exc}'
    finally:
        if tmp:
            shutil.rmtree(tmp, ignore_errors=True)
    record['wall_time_s'] = time.perf_counter() - t0
    return record


def metric_value(metrics, path):
    """The value at the dotted ``path`` of a metrics dict (None where it is missing)."""
    node = metrics
    for part in path.split('.'):
        if isinstance(node, dict) and part in node:
            node = node[part]
        elif isinstance(node, list) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        else:
            return None
    return node


class _Progress:
    """``sweep NAME: 5/12 runs (1 failed, 3 resumed)  elapsed 10.2 s  ETA 14.3 s``.

    The ETA is the remaining runs at the rate since the first run finished (the time to
    the first one includes starting the cluster and the workers' imports).
    """

    def __init__(self, name, total, skipped, stream):
        self.name, self.total, self.skipped, self.stream = name, total, skipped, stream
        self.done = self.failed = 0
        self.t0 = time.perf_counter()
        self.t_first = None
        self.tty = stream is not None and hasattr(stream, 'isatty') and stream.isatty()

    def update(self, record):
        self.done += 1
        self.failed += record['status'] != 'ok'
        now = time.perf_counter()
        if self.t_first is None:
            self.t_first = now
        if self.stream is None:
            return
        elapsed = now - self.t0
        todo = self.total - self.skipped - self.done
        eta = ((now - self.t_first) / (self.done - 1) if self.done > 1
               else elapsed) * todo
        line = (f'sweep {self.name}: {self.skipped + self.done}/{self.total} runs '
                f'({self.failed} failed, {self.skipped} resumed)  elapsed {elapsed:.1f} s  '
                f'ETA {eta:.1f} s')
        end = '' if self.tty and todo else '\n'
        print(('\r' if self.tty else '') + line, end=end, file=self.stream, flush=True)


def _tasks(spec, points, out_dir, version):
    where = spec.scenario_path
    return [{'key': p.key, 'index': p.index, 'scenario': p.scenario, 'where': where,
             'base_dir': spec.scenario_dir, 'code_version': version,
             'bag_dir': str(out_dir / 'runs' / p.key) if spec.keep_bags else None}
            for p in points]


def _write_record(out_dir, point, spec, record, version):
    record = dict(record, point=point.index, params=point.params, sample=point.sample,
                  seed=spec.seed, code_version=version)
    path = out_dir / 'runs' / f'{point.key}.json'
    tmp = path.with_suffix('.json.tmp')
    tmp.write_text(json.dumps(record, indent=1, allow_nan=False) + '\n')
    os.replace(tmp, path)  # atomic: a killed sweep leaves whole records only
    return record


def _local_cluster(workers):
    from distributed import LocalCluster

    return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                        host='127.0.0.1', dashboard_address=None)


def map_unordered(fn, items, workers=None, scheduler=None, client=None, catch=False):
    """Yield ``(i, fn(items[i]))`` as each call finishes, on the engine the options choose.

    The engine of :func:`run_sweep`, for any picklable module-level ``fn`` (the thesis
    reproduction and Sec. 5.3 run their jobs through it): ``workers=1`` calls ``fn`` here,
    in order; else Dask runs the calls (``client``, or an existing ``scheduler``, or a
    local cluster of ``workers`` processes, default one per core, started and closed
    here). Dask starts the calls in the order of ``items`` (put the longest first).

    Args:
        fn: The function (imported by name on the workers).
        items: Its arguments, one call each.
        workers: 1: serial; N: a local Dask cluster of N worker processes.
        scheduler: Address of an existing Dask scheduler.
        client: A ``distributed.Client`` to use.
        catch: Yield an exception a Dask call ended with (e.g. ``KilledWorker`` after a
            worker died running it ``allowed-failures`` times) as its result instead of
            raising it.
    """
    items = list(items)
    if client is None and scheduler is None and workers == 1:
        for i, item in enumerate(items):
            yield i, fn(item)
        return
    if not items:
        return
    from distributed import as_completed

    with _dask_client(workers, scheduler, client) as dask:
        futures = dask.map(fn, items, pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        for future in as_completed(futures):
            try:
                result = future.result()
            except Exception as exc:
                if not catch:
                    raise
                result = exc
            yield index[future.key], result
            future.release()


@contextlib.contextmanager
def _dask_client(workers, scheduler, client):
    """``client``, or one of ``scheduler``, or of a new local cluster (closed at the end)."""
    if client is not None:
        yield client
        return
    from distributed import Client

    cluster = None if scheduler else _local_cluster(workers or os.cpu_count() or 1)
    try:
        with Client(scheduler or cluster) as own:
            yield own
    finally:
        if cluster is not None:
            cluster.close()


def run_sweep(spec, out_dir, workers=None, scheduler=None, resume=False, stream=sys.stderr,
              client=None, on_record=None):
    """Run every point of ``spec`` and write ``out_dir/results.csv``.

    Args:
        spec: A :class:`~ifc_spg.offline.sweep_spec.SweepSpec`.
        out_dir: The output directory (``runs/`` and ``results.csv`` inside).
        workers: 1: serial in this process; N > 1 or None (one per core): a local Dask
            cluster of N worker processes.
        scheduler: Address of an existing Dask scheduler (``tcp://HOST:8786``).
        resume: Skip points whose record exists in ``out_dir/runs``.
        stream: Where the progress line goes (None: nowhere).
        client: A ``distributed.Client`` to use (tests, notebooks); overrides the above.
        on_record: Called with each new record (after it is written).

    Returns:
        ``{'points', 'ran', 'skipped', 'failed', 'table'}``.

    Raises:
        ParameterError: ``out_dir`` holds results but ``resume`` is false.
    """
    out_dir = Path(out_dir)
    runs = out_dir / 'runs'
    if runs.is_dir() and any(runs.glob('*.json')) and not resume:
        raise ParameterError(f"'{out_dir}' holds sweep results; pass --resume to run only the "
                             'missing points, or choose another -o directory')
    runs.mkdir(parents=True, exist_ok=True)
    version = code_version()
    points = spec.points(version)
    todo = [p for p in points if not (resume and (runs / f'{p.key}.json').is_file())]
    progress = _Progress(spec.name, len(points), len(points) - len(todo), stream)
    by_key = {p.key: p for p in todo}
    failed = [0]

    def emit(point, record):
        record = _write_record(out_dir, point, spec, record, version)
        failed[0] += record['status'] != 'ok'
        progress.update(record)
        if on_record is not None:
            on_record(record)

    tasks = _tasks(spec, todo, out_dir, version)
    try:
        with contextlib.closing(map_unordered(run_point, tasks, workers, scheduler, client,
                                              catch=True)) as results:
            for i, record in results:
                if isinstance(record, Exception):  # e.g. KilledWorker: the row says so
                    record = {'key': tasks[i]['key'], 'status': 'error', 'metrics': None,
                              'error': f'{type(record).__name__}: {record}',
                              'wall_time_s': None}
                emit(by_key[tasks[i]['key']], record)
    finally:
        table = write_table(spec, out_dir, points)
    return {'points': len(points), 'ran': len(todo), 'skipped': len(points) - len(todo),
            'failed': failed[0], 'table': table}


def read_records(out_dir, points):
    """The records of ``points`` found in ``out_dir/runs`` (in point order)."""
    out = []
    for p in points:
        path = Path(out_dir) / 'runs' / f'{p.key}.json'
        if path.is_file():
            out.append(json.loads(path.read_text()))
    return out


def _cell(value):
    if value is None:
        return ''
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else str(value)
    if isinstance(value, (dict, list, tuple)):
        return json.dumps(value, sort_keys=True)
    return value


def rows(spec, records):
    """One dict per record: :data:`FIXED_COLUMNS`, the axes, the metrics (plain values)."""
    out = []
    for r in records:
        row = {c: r.get(c) for c in FIXED_COLUMNS}
        row.update({a.path: r['params'].get(a.path) for a in spec.axes})
        row.update({m: metric_value(r.get('metrics') or {}, m) for m in spec.metrics})
        out.append(row)
    return out


def write_table(spec, out_dir, points):
    """Write ``out_dir/results.csv`` from the records; its path."""
    path = Path(out_dir) / RESULTS
    columns = list(FIXED_COLUMNS) + [a.path for a in spec.axes] + list(spec.metrics)
    tmp = path.with_suffix('.csv.tmp')
    with open(tmp, 'w', newline='', encoding='utf8') as f:
        writer = csv.writer(f)
        writer.writerow(columns)
        for row in rows(spec, read_records(out_dir, points)):
            writer.writerow([_cell(row[c]) for c in columns])
    os.replace(tmp, path)
    return path
