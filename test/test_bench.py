"""``ifc-spg bench`` runs end to end (a few ticks; the numbers themselves are not tested)."""

import math

from benchmarks.bench import format_report, run_benchmarks
from ifc_spg.cascade import daqp as daqp_cascade


def test_bench_runs_every_row_and_reports_the_machine_baseline():
    res = run_benchmarks(ticks=40, solvers=('daqp',), progress=False, first_runs=1)
    rows = {r['stack']: r for r in res['stacks']}
    assert set(rows) == {'lbr_table_4_1', 'icub_table_3_7'}
    for r in rows.values():
        assert r['ticks'] == 40 and r['status'] == {'ok': 40}
        assert 0 < r['p50_us'] <= r['p99_us'] <= r['max_us']
        assert r['baseline']['ticks'] == 40 and r['baseline']['p50_us'] > 0
    assert res['pink']['ours']['ticks'] == res['pink']['pink']['ticks'] == 40
    assert [r['stack'] for r in res['native']] == ['lbr_table_4_1', 'icub_table_3_7']
    assert all(r['native']['ticks'] == r['numpy']['ticks'] == 40 for r in res['native'])
    report = format_report(res)
    assert 'machine baseline' in report and res['implementation'] in report
    assert 'C kernels vs their numpy reference code' in report
    if daqp_cascade.native is not None:
        assert [r['stack'] for r in res['daqp_native']] == ['lbr_table_4_1', 'icub_table_3_7']
        for r in res['daqp_native']:
            assert r['c']['ticks'] == r['python']['ticks'] == 40
            assert 0 < r['calls_c'] < r['calls_python']
        assert "Level solves from C vs through DAQP's Python module" in report
    f = res['first_ticks']
    for mode in ('prepared', 'lazy'):
        assert f[mode]['first']['ticks'] == f[mode]['switch']['ticks'] == f['repeats']
        assert f[mode]['steady']['ticks'] == 198 * f['repeats']
    assert 'stack-switch tick' in report and 'prepared/lazy' in report
    pf = res['process_first_ticks']
    for mode in ('warm_up', 'no_warm_up'):
        assert len(pf[mode]['runs']) == 1 and pf[mode]['first_us'] > 0
        assert pf[mode]['first_ratio'] > 0 and pf[mode]['switch_ratio'] > 0
    assert 'first tick of a process' in report


def test_warm_start_bench_runs_and_the_explicit_working_sets_cost_no_iterations():
    """Working sets kept by the cascade (restorable from spg/state) warm-start DAQP as well as
    DAQP's own: the same iterations per tick within 3 % (3.23 and 7.40 vs 7.43 measured)."""
    from benchmarks.warm_start_bench import run

    rows = {r['stack']: r for r in run(ticks=150, warmup=20)}
    assert set(rows) == {'lbr_table_4_1', 'icub_table_3_7'}
    for r in rows.values():
        ours, daqp = r['explicit'], r['daqp_internal']
        assert ours['ticks'] == daqp['ticks'] == 150 and r['ratio_p50'] > 0
        assert 0 < ours['iterations_per_tick'] <= 1.03 * daqp['iterations_per_tick'], r


def test_scaling_bench_runs_every_point_and_fits_finite_exponents(tmp_path):
    """``ifc-spg bench --scaling`` with a few ticks: every axis point, exponents, JSON, figure."""
    import json

    from benchmarks.bench import main
    from benchmarks.scaling_bench import AXES

    out, figure = tmp_path / 'scaling.json', tmp_path / 'scaling.png'
    assert main(['--scaling', '--ticks', '20', '--json', str(out), '--figure', str(figure)]) == 0
    res = json.loads(out.read_text())
    assert set(res['axes']) == set(res['exponents']) == {'dof', 'levels', 'rows'}
    for axis, xs in AXES.items():
        rows = res['axes'][axis]
        assert [r['x'] for r in rows] == list(xs)
        for r in rows:
            assert r['ticks'] == 20 and r['status'] == {'ok': 20}, (axis, r)
            assert 0 < r['p50_us'] <= r['p99_us'] <= r['max_us']
        assert math.isfinite(res['exponents'][axis])
    assert [r['dof'] for r in res['axes']['dof']] == [7, 17, 34]
    assert [r['levels'] for r in res['axes']['levels']] == list(range(1, 11))
    assert [r['rows'][0] for r in res['axes']['rows']] == [1, 3, 6, 12]
    assert figure.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
