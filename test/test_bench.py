"""``ifc-spg bench`` runs end to end (a few ticks; the numbers themselves are not tested)."""

from ifc_spg.tools.bench import format_report, run_benchmarks


def test_bench_runs_every_row_and_reports_the_machine_baseline():
    res = run_benchmarks(ticks=40, solvers=('daqp',), progress=False)
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
    f = res['first_ticks']
    for mode in ('prepared', 'lazy'):
        assert f[mode]['first']['ticks'] == f[mode]['switch']['ticks'] == f['repeats']
        assert f[mode]['steady']['ticks'] == 198 * f['repeats']
    assert 'stack-switch tick' in report and 'prepared/lazy' in report
