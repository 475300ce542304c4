"""The collision-avoidance rows of ``ifc-spg bench`` run end to end (numbers not tested)."""

import importlib.util

from benchmarks.collision_bench import bench_collision, format_collision


def test_collision_bench_runs_every_robot_and_mink_when_installed():
    res = bench_collision(ticks=30, progress=False)
    rows = {r['robot']: r for r in res['tick']}
    assert set(rows) == {'lbr_iiwa14', 'accrea_dual_arm', 'icub_upper_body'}
    assert rows['lbr_iiwa14']['pairs'] == 47 and rows['accrea_dual_arm']['pairs'] == 218
    assert rows['icub_upper_body']['pairs'] == 564  # table_4_1_icub_self_collision.yaml says so
    assert set(res['mink_skipped']) == {'icub_upper_body'}
    for r in rows.values():
        assert r['with']['ticks'] == r['without']['ticks'] == 30
        assert r['status'] in ('ok', 'fallback')
    report = format_collision(res)
    assert 'added p50' in report
    if importlib.util.find_spec('mink') is None:
        assert 'mink is not installed' in report
        return
    assert {r['robot'] for r in res['mink']} == {'lbr_iiwa14', 'accrea_dual_arm'}
    for r in res['mink']:
        assert r['ours']['ticks'] == r['mink']['ticks'] == 30
        # mink drops its own adjacent pairs; the remaining ones are ours
        assert 0 < r['mink_pairs'] <= r['pairs']
    assert 'ratio ours/mink' in report
