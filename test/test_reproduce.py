"""Short versions of the thesis experiments (experiments.reproduce --quick): each claim's
direction, with a margin, from real lockstep simulation runs (no stored results), and the
pass rules of experiments/claims.py (evaluated as written; failing claims reported).

Each experiment runs once per session (about 70 s in all on 2 cores); a test fails when the
effect it names disappears (e.g. the K sweep with a flat position error, Table 4.2 with the
virtual tool leaving the box, Table 4.1 without the 1b torque band).
"""

import io
import json

import numpy as np
import pytest

from benchmarks import kdl as _kdl
from experiments import ch3, ch5, claims, report, report_ch6, reproduce
from ifc_spg.errors import ParameterError
from ifc_spg.offline.runner import find_config_dir, load_scenario

_KDL_OK, _KDL_WHY = _kdl.available()

_BY_NAME = {e.name: e for e in reproduce.ALL_EXPERIMENTS}


@pytest.fixture(scope='module')
def quick(tmp_path_factory):
    out = tmp_path_factory.mktemp('reproduce')
    cache, done = {}, {}

    def get(name):
        if name not in done:
            check, _, _ = reproduce.run_experiment(_BY_NAME[name], out, quick=True,
                                                   figures=False, cache=cache)
            done[name] = check
        return done[name]
    return get


def test_every_thesis_scenario_loads_and_names_its_table():
    files = sorted((find_config_dir() / 'scenarios').glob('thesis_*.yaml'))
    used = {spec.scenario for e in reproduce.EXPERIMENTS for spec in e.runs}
    assert {f.name for f in files} == used  # every scenario file is part of an experiment
    for f in files:
        sc = load_scenario(f)
        assert sc.name == f.stem
        assert 'Thesis Table' in f.read_text()


def test_stiffness_override_reaches_simulation_and_spg(tmp_path):
    from ifc_spg.offline.runner import robot_with_ifc

    over = ch3._surface_overrides(stiffness=40.0)
    sc = load_scenario(find_config_dir() / 'scenarios' / 'thesis_3_2_surface_tracking.yaml',
                       overrides=over)
    robot = robot_with_ifc(sc)
    np.testing.assert_allclose(robot.stiffness, 40.0)
    np.testing.assert_allclose(robot.damping, ch3._LBR4_DAMPING * np.sqrt(0.2), atol=1e-4)
    with pytest.raises(ParameterError, match='sim.stiffness'):
        robot_with_ifc(load_scenario(
            find_config_dir() / 'scenarios' / 'thesis_3_2_surface_tracking.yaml',
            overrides={'sim': {'stiffness': [1.0, 2.0]}}))


def test_unknown_experiment_is_named():
    with pytest.raises(ParameterError, match='table_4_5'):
        reproduce.run_experiments('/nonexistent', only=['table_4_6'])


def test_report_table(tmp_path):
    rows = [{'name': 'x', 'table': 'Table 9.9', 'claim': 'c', 'passed': False,
             'summary': 'a | b', 'numbers': {}, 'figure': 'figures/x.png', 'wall_s': 1.0,
             'scenarios': ['thesis_x.yaml'],
             'claims': [{'id': 'x.one', 'experiment': 'x', 'source': 'Fig. 9', 'thesis': '8 N',
                         'metric': 'm', 'ours': '9 N', 'value': 9.0, 'rule': '< 4 N',
                         'passed': False, 'history': 'widened'},
                        {'id': 'x.two', 'experiment': 'x', 'source': 'Fig. 9', 'thesis': 't',
                         'metric': 'm2', 'ours': '1', 'value': 1.0, 'rule': '> 0',
                         'passed': True, 'history': ''}]},
            {'name': 'y', 'table': 'Table 9.9 (cause)', 'claim': 'c2', 'passed': True,
             'ours': True, 'summary': 's', 'numbers': {}, 'figure': None, 'wall_s': 1.0,
             'scenarios': ['thesis_x.yaml'],
             'claims': [{'id': 'y.one', 'experiment': 'y', 'source': 'Fig. 9', 'thesis': 't',
                         'metric': 'm3', 'ours': '2', 'value': 2.0, 'rule': '> 1',
                         'passed': True, 'history': ''}]}]
    report.write_report(rows, tmp_path / 'R.md', wall_s=90.0)
    text = (tmp_path / 'R.md').read_text()
    assert '| x.one | Fig. 9 | 8 N | m | 9 N | < 4 N | **fails** | widened |' in text
    assert '| x.two | Fig. 9 | t | m2 | 1 | > 0 | holds |  |' in text
    # an experiment of ours (a cause test) is counted apart from the thesis' experiments
    assert ('Summary: 2 of 3 claims hold; 0 of the 1 thesis experiments reproduced (all of '
            'their claims hold); 1 of 1 of our own experiments (y: tests of a cause).') in text
    assert 'Failing: x.one.' in text and '1.5 min wall' in text
    assert '![x](figures/x.png)' in text
    json.dumps(rows)


@pytest.mark.slow
def test_fri_delay_reaches_the_lbr_runs_and_only_them(tmp_path):
    """--fri-delay (issue 29 item 2): an LBR experiment's numbers change with the delay, the
    iCub's (no FRI) do not; the rows and the report say which ran delayed."""
    rows = {}
    for delay in (0, 1):
        out = tmp_path / f'd{delay}'
        rows[delay] = {r['name']: r for r in reproduce.run_experiments(
            out, quick=True, only=['table_4_2', 'table_3_6'], figures=False,
            stream=io.StringIO(), fri_delay=delay)}
    text = (tmp_path / 'd1' / 'REPORT.md').read_text()
    assert 'Ran delayed: table_4_2.' in text and 'scenario does not' in text
    assert rows[1]['table_4_2']['fri_delay'] == 1 and rows[1]['table_3_6']['fri_delay'] == 0
    assert rows[1]['table_4_2']['numbers'] != rows[0]['table_4_2']['numbers']
    assert rows[1]['table_3_6']['numbers'] == rows[0]['table_3_6']['numbers']
    with pytest.raises(ParameterError, match='fri_delay'):
        reproduce.run_experiments(tmp_path / 'bad', only=['table_4_2'], fri_delay=-1)


def test_every_claim_names_an_experiment_source_and_rule():
    names = set(reproduce.experiment_names())
    ids = [c.id for c in claims.CLAIMS]
    assert len(ids) == len(set(ids))
    assert {c.experiment for c in claims.CLAIMS} == names  # every experiment has claims
    for c in claims.CLAIMS:
        assert c.id.startswith(c.experiment + '.') and c.source and c.thesis and c.metric
        assert c.op in ('<', '<=', '>', '>=', 'abs<=', 'factor', 'true')
        assert c.rule()


def test_claim_rules_fail_as_written():
    """A value just past a bound fails; a missing number fails (it is never a pass)."""
    by_id = {c.id: c for c in claims.CLAIMS}
    c = by_id['table_4_5.bounded']  # >= -0.1 mJ
    row = lambda v: claims.evaluate('table_4_5', v)  # noqa: E731
    base = {'no_pspm': {'energy_in_end_j': -1.0, 'energy_in_mid_j': 0.0,
                        'error_amplitude_last_1s_rad': 1.0},
            'pspm': {'energy_in_min_j': -0.00211, 'error_amplitude_last_1s_rad': 0.1},
            'c2_j': 0.002}
    got = {r['id']: r for r in row(base)}
    assert not got['table_4_5.bounded']['passed']  # -2.11 mJ against -2 mJ: past the 0.1 mJ
    base['pspm']['energy_in_min_j'] = -0.00209
    assert {r['id']: r for r in row(base)}['table_4_5.bounded']['passed']
    assert c.bound == -1e-4
    f = by_id['table_5_1.fixed_jc_abs']
    assert f.rule().startswith('0.29 ... 1.16 N')
    none = {r['id']: r for r in claims.evaluate('table_4_5', {})}
    assert not any(r['passed'] for r in none.values())
    assert {r['ours'] for r in none.values()} == {'n/a'}


def test_report_6_both_inertia_readings():
    """Report Ch. 6: scenario 1 sticks (mu* = 5 Nm), scenario 2 slips with |mu*| = 10 Nm;
    -1 Nm on I = 0.25 (as described) gives -4 rad/s^2, on I = 2.25 (KDL reading, COM 1.5 m)
    -0.444: only the inferred reading reproduces the printed -0.44."""
    check, _, _ = reproduce.run_experiment(_BY_NAME['report_6'], '/nonexistent', quick=True)
    n = check.numbers
    for key in ('described', 'kdl'):
        assert n[key]['s1_mu'] == pytest.approx(5.0) and n[key]['s1_stick']
        assert abs(n[key]['s2_mu']) == pytest.approx(10.0) and not n[key]['s2_stick']
    assert n['described']['s2_qdd'] == pytest.approx(-4.0)
    assert n['kdl']['s2_qdd'] == pytest.approx(-1.0 / 2.25)
    got = {c['id']: c['passed'] for c in check.claims}
    assert got['report_6.s2_qdd_kdl'] and not got['report_6.s2_qdd_described']
    assert not check.passed
    # the Gauss-function shape: fully constrained, qdd is the constraint's whatever mu is
    g = n['gauss']
    assert g['full']['qdd_range_rad_s2'] == pytest.approx([5.0, 5.0], abs=1e-9) or \
        g['full']['qdd_range_rad_s2'] == pytest.approx([-5.0, -5.0], abs=1e-9)
    assert g['partial']['qdd_range_rad_s2'][1] - g['partial']['qdd_range_rad_s2'][0] > 1.0
    x = np.linspace(-1.0, 1.0, 21)
    assert report_ch6._fit_residual(x, 3.0 * x + 1.0, 1) < 1e-12
    assert report_ch6._fit_residual(x, x ** 2, 1) > 0.1
    assert report_ch6._fit_residual(x, x ** 2, 2) < 1e-12


def test_report_6_not_run_without_kdl(monkeypatch):
    """Without KDL the cause experiment says why it did not run, and the note says n/a."""
    from benchmarks import kdl

    monkeypatch.setattr(kdl, 'available', lambda: (False, 'KDL not found (test)'))
    k = report_ch6._kdl_native()
    assert k == {'not_run': 'KDL not found (test)'}
    assert 'not run (KDL not found (test))' in report_ch6._kdl_text(k)
    assert 'gives n/a rad/s^2' in report.note_text('report_6', {'kdl_native': k})


@pytest.mark.skipif(not _KDL_OK, reason=f'KDL itself: {_KDL_WHY}')
def test_report_6_kdl_reads_the_cog_in_the_tip_frame():
    """KDL's own Vereshchagin solver on the report's arm (1 kg, 1 m, -1 Nm): the cog written
    as the report states it, 0.5 m along x, is read in the tip frame, 1.5 m from the joint
    (I = 2.25 kg m^2, the report's -0.44 rad/s^2); -0.5 m in the tip frame is the arm as
    described (I = 0.25 kg m^2, our solver's -4 rad/s^2)."""
    k = report_ch6._kdl_native()
    assert k['as_written'] == pytest.approx(-1.0 / 2.25, rel=1e-9)
    assert k['kdl_convention'] == pytest.approx(-1.0 / 0.25, rel=1e-9)
    check, _, _ = reproduce.run_experiment(_BY_NAME['report_6'], '/nonexistent', quick=True)
    assert check.numbers['kdl_native'] == k
    assert check.numbers['kdl_native']['kdl_convention'] == \
        pytest.approx(check.numbers['described']['s2_qdd'], rel=1e-9)


def test_table_5_1_lift_time_model_predicts_the_unfinished_runs():
    """Task-specification lift times t = c K / kappa: c from the finished fixed-direction
    runs (median), the unfinished runs of both cases get c K / kappa."""
    def row(k, kappa, t):
        return {'stiffness': k, 'kappa': kappa, 'time_to_open_jc_ts_s': [1.0, t]}
    fixed = [row(k, kappa, None if (k, kappa) == (200.0, 5.0) else 7.0 * k / kappa)
             for k in (40.0, 100.0, 200.0) for kappa in (5.0, 10.0, 15.0)]
    fixed[0]['time_to_open_jc_ts_s'][1] *= 1.2    # an outlier does not move the median
    m = ch5._lift_time_model(fixed, [row(100.0, 10.0, None), row(40.0, 5.0, 3.0)])
    assert m['c_s_n_per_nm'] == pytest.approx(7.0) and m['finished'] == 8
    assert m['c_range'] == pytest.approx([7.0, 8.4])
    assert [(r['case'], r['predicted_s']) for r in m['not_finished']] == [
        ('fixed_direction', pytest.approx(280.0)), ('sma_estimator', pytest.approx(70.0))]
    txt = report._lift_model_text(m, 240.0)
    assert 'fixed direction K = 200 / kappa = 5 would take 280 s' in txt and '240 s' in txt
    assert ch5._lift_time_model([row(40.0, 5.0, None)]) is None


def test_comparison_rejects_a_non_positive_damping_scale():
    from ifc_spg.offline.constrained_evaluate import QUICK_COMPARISON, comparison

    for bad in (0.0, -1.0, float('nan')):
        with pytest.raises(ParameterError, match='damping_scale'):
            comparison(cases=('fixed_direction',), damping_scale=bad, **QUICK_COMPARISON)


def test_table_3_6_push_clamps_are_the_onsets_between_pushes():
    """Alg. C.2's clamp onsets (a joint's q_v comes within dl_crit of a limit) are assigned
    to the push they follow, up to the next push."""
    from types import SimpleNamespace

    from ifc_spg.cascade.nullspace import CRITICAL_DISTANCE

    t = np.arange(0.0, 10.0, 0.002)
    q_v = np.zeros((len(t), 2))
    lo, hi = np.array([-1.0, -1.0]), np.array([1.0, 1.0])
    near = hi[1] - 0.5 * CRITICAL_DISTANCE
    q_v[(t >= 7.5) & (t < 8.0), 1] = near        # joint b reaches its clamp in push 3
    q_v[t >= 8.4, 0] = lo[0] + 0.5 * CRITICAL_DISTANCE    # joint a after it, before the end
    q_v[(t >= 2.0) & (t < 2.1), 0] = 0.9 * hi[0]  # far from the clamp: no onset
    run = SimpleNamespace(
        s=SimpleNamespace(q_v=q_v, t_cmd=t, joint_names=['a', 'b']),
        robot=SimpleNamespace(q_min=lo, q_max=hi),
        pushes=[{'at': 1.0, 'duration': 1.0}, {'at': 4.0, 'duration': 1.0},
                {'at': 7.0, 'duration': 1.0}])
    got = ch3._push_clamps(run)
    assert got == [[], [], [(7.5, 'b'), (8.4, 'a')]]
    assert report._clamp_list(got) == 'b at t = 7.50 s (push 3), a at t = 8.40 s (push 3)'
    assert report._clamp_list([[], []]) == 'none'


def test_table_3_2_surface_tracking(quick):
    n = quick('table_3_2').numbers
    assert n['contact_lost_share'] < 0.05
    assert n['position_error_rms_m'] < 0.02
    assert n['virtual_position_error_rms_m'] < 0.002


def test_fig_3_15_position_error_falls_with_stiffness(quick):
    n = quick('k_sweep').numbers
    assert n['stiffness'] == [40.0, 400.0]
    low_k, high_k = n['position_error_rms_m']
    assert high_k < 0.5 * low_k


def test_fig_3_14_errors_rise_with_speed(quick):
    n = quick('speed_sweep').numbers
    slow, fast = n['position_error_rms_m']
    assert fast > 1.5 * slow
    f_slow, f_fast = n['force_error_rms_n']
    assert f_fast > 2.0 * f_slow


def test_table_3_3_wiping(quick):
    n = quick('table_3_3').numbers
    assert n['contact_lost_share'] < 0.05
    assert n['position_error_rms_m'] < 0.03


def test_table_3_4_relaxed_rotation_avoids_the_joint_limit(quick):
    """Nullspace baseline (Ch. 3) without Ch. 4's velocity box, from Table 3.2's start pose
    and circle (issue 29): the pen stays on the table and the relaxed variant reaches no
    limit; the DAQP + PSPM variant beside it keeps the box, so its every per-tick change of
    qdot_v stays within a_max dT. The claims are evaluated as written: from this pose no
    joint comes near a limit (the check prints the closest approach), so limit_full and the
    discontinuity claim follow the numbers, whichever way they go."""
    n = quick('table_3_4').numbers
    for v in ('full', 'relaxed'):
        # on the table most of the time (v1-v4 at R = 0.15 m: off for 61-77 %); the quick
        # run's 2.5 s window is mostly the circle's start (full run: the contact claim)
        assert n[v]['contact_lost_share'] < 0.2, (v, n[v])
        assert 1 <= n[v]['closest_limit_joint'] <= 7 and n[v]['closest_limit_deg'] >= 0.0
    assert n['relaxed']['ticks_at_joint_limit'] == 0
    from ifc_spg.model import RobotModel
    bound = float(np.linalg.norm(RobotModel.from_config('lbr4').a_max * 0.002))
    for v in ('full_daqp', 'relaxed_daqp'):
        assert n[v]['max_qdot_v_jump_rad_s'] <= bound + 1e-9, (v, n[v], bound)
    got = {c['id']: c['passed'] for c in quick('table_3_4').claims}
    assert got['table_3_4.peak_qdot'] == (n['relaxed']['peak_qdot_norm_rad_s'] <
                                          n['full']['peak_qdot_norm_rad_s'])
    assert got['table_3_4.limit_full'] == (n['full']['ticks_at_joint_limit'] > 0)
    for name in ('full', 'relaxed'):  # the Ch. 3 baseline runs without the box
        assert not load_scenario(find_config_dir() / 'scenarios' /
                                 f'thesis_3_4_circle_drawing_{name}.yaml').spg.velocity_box


def test_table_3_5_cup_holding_keeps_the_orientation_while_pushed(quick):
    n = quick('table_3_5').numbers
    assert n['max_displacement_m'] > 0.03  # pushed around
    assert n['max_orientation_error_settled_deg'] < 1.0
    # with the box saturated inside the hierarchy (SNS) the virtual orientation, the first
    # level, is held (it drifted by 1.1 deg when the baseline clipped per joint)
    assert n['max_virtual_orientation_error_deg'] < 0.05


def test_table_3_6_icub_cup_holding_with_stiff_wrists(quick):
    """One 3 N push (1-2 s), 2 s to settle: the physical hand orientation comes back (it was
    > 5 deg while pushed; 0.5 s after the push it may still be above the claim's 3 deg), the
    virtual one never moved, and the stiff wrist joints stay at q_bar and track q_v."""
    n = quick('table_3_6').numbers
    assert n['settle_s'] == 0.5
    assert n['max_displacement_m'] > 0.03
    assert n['max_orientation_error_deg'] > 5.0  # the push did tilt the compliant arm
    assert n['orientation_error_end_deg'] < 1.0
    assert n['max_virtual_orientation_error_deg'] < 0.1
    assert n['max_wrist_virtual_deviation_deg'] < 0.5
    assert n['max_wrist_tracking_error_rad'] < 1e-3


def test_table_3_7_icub_wiping_keeps_contact(quick):
    """8 s of the iCub wiping run (the first y step at 4 s): the left forearm's wiping pad
    stays on the table (smoothed f_z below -1 N) >= 90 % of the time from 1 s and f_z is
    within 3.5 N RMS of -7 N (the ground-truth contact force, not the SPG's estimate). The
    right-hand cup criterion of the check (< 3 deg, < 20 mm) is not asserted here: the torso
    yaw drift still breaks it (see the check's text)."""
    n = quick('table_3_7').numbers
    assert n['contact_lost_share'] < 0.1
    assert n['force_error_rms_n'] < 3.5


def test_table_4_1_obstacle_torque_and_force_bands(quick):
    n = quick('table_4_1').numbers
    for v in ('1a_3a', '1b_3a', '1a_3b', '1b_3b'):
        assert n[v]['obstacle_hit_s'] is not None and n[v]['obstacle_hit_s'] < 3.6
        assert n[v]['max_obstacle_force_n'] > 5.0  # the obstacle resists in every variant
    for v in ('1b_3a', '1b_3b'):
        assert n[v]['max_abs_static_torque_nm'] <= 5.25
    for v in ('1a_3b', '1b_3b'):
        assert n[v]['max_abs_static_tangential_force_n'] <= 10.5
        assert n[v]['max_abs_task_tangential_force_n'] <= 10.5
    # without the bands the obstacle drives both beyond them (what the bands hold)
    assert n['1a_3a']['max_abs_static_torque_nm'] > 7.0
    assert n['1a_3a']['max_abs_static_tangential_force_n'] > 14.0
    assert n['1a_3a']['max_obstacle_force_n'] > 14.0
    # with 1b or 3b the virtual tool stops inside the obstacle instead of running through
    assert n['1b_3b']['max_virtual_y_m'] < n['1a_3a']['max_virtual_y_m'] - 0.01
    for v in ('1a_3a', '1b_3a'):  # Fig. 4.14 (VIII): beyond the face (6 cm from the start)
        assert n[v]['max_virtual_penetration_m'] == pytest.approx(
            max(0.0, n[v]['max_virtual_y_m'] - 0.06))


def test_table_4_2_virtual_tool_stays_in_the_box(quick):
    n = quick('table_4_2').numbers
    for v in ('high_k', 'low_k'):
        assert n[v]['max_virtual_outside_m'] < 1e-3
    assert n['high_k']['max_physical_outside_m'] > 2e-3
    assert n['low_k']['max_physical_outside_m'] > 2.0 * n['high_k']['max_physical_outside_m']


def test_table_4_3_pose_held_until_the_wrench_bound(quick):
    n = quick('table_4_3').numbers
    assert n['error_small_push_m'] < 0.005
    assert n['error_large_push_m'] > 0.02
    assert n['static_force_large_push_n'] < 10.5
    assert n['error_end_m'] < 0.15 * n['error_large_push_m']  # returning


def test_table_4_4_motion_only_along_z_ee(quick):
    n = quick('table_4_4').numbers
    assert n['max_along_z_ee_m'] > 0.02
    along_first, _ = n['after_each_push_along_perp_m'][0]
    assert abs(along_first) > 0.01
    assert max(abs(p) for _, p in n['after_each_push_along_perp_m']) < 0.003


def test_table_4_5_pspm_bounds_the_injected_energy(quick):
    """With the thesis' plant (D5 = 2.5 Nms/rad) the lockstep loop is stable: no energy
    is generated without PSPM and the instability claims fail (reported, not hidden); with
    PSPM the port stays passive to 0.1 mJ."""
    n = quick('table_4_5').numbers
    c2 = n['c2_j']
    off, on = n['no_pspm'], n['pspm']
    assert on['energy_in_min_j'] >= -c2 - 1e-4
    assert on['tank_energy_min_j'] >= 0.0
    got = {c['id']: c['passed'] for c in quick('table_4_5').claims}
    assert got['table_4_5.unstable'] == (off['energy_in_end_j'] < -2 * c2)
    assert got['table_4_5.bounded']


@pytest.mark.slow
def test_table_5_1_task_specification_cuts_the_perpendicular_force(tmp_path):
    """Table 5.1 (5.5.3), quick: one (K, kappa) pair of the grid, the full 0.29 m lift;
    the task-specification strategy has less than 30 % of the joint-compliance strategy's
    RMS |f_perp| (thesis: -70 % / -86 %), with the fixed direction and with the SMA
    estimator seeded 45 deg off."""
    check, _, _ = reproduce.run_experiment(ch5.TABLE_5_1, tmp_path, quick=True,
                                           figures=False)
    n = check.numbers
    for case in ('fixed_direction', 'sma_estimator'):
        jc, ts = n[case]['rms_f_perp_jc_to_ts_n']
        assert n[case]['opened'] == {'joint_compliance': 1, 'task_specification': 1}, n[case]
        assert ts < 0.3 * jc, (case, n[case])
        assert n[case]['reduction_percent'] == pytest.approx(100.0 * (jc - ts) / jc)
        (row,) = n[case]['runs']
        assert (row['stiffness'], row['kappa']) == (40.0, 15.0)
    assert n['sma_initial_error_deg'] == 45.0 and n['runs_total'] == 4
    # the dead-band ablation (ours, no claim): the same SMA runs at v_th = w0 = 2 mm/s
    low = n['sma_estimator_vth']
    assert low['v_threshold_m_s'] == ch5.T51_ABLATION_VTH == 0.002
    (row,) = low['runs']
    assert (row['stiffness'], row['kappa']) == (40.0, 15.0)
    assert row['rms_f_perp_jc_ts_n'] != n['sma_estimator']['runs'][0]['rms_f_perp_jc_ts_n']
    for r in (row, n['sma_estimator']['runs'][0]):  # lift speed = travel / lift time
        speed, t = r['mean_speed_jc_ts_m_s'][1], r['time_to_open_jc_ts_s'][1]
        assert speed == pytest.approx(0.29 / t, rel=0.01)
    assert 'v_th = w0 = 2 mm/s' in check.summary
    # the damping ablation (ours, no claim): the fixed-direction run with the plant's D
    # scaled; the damping force D qdot is part of the measured perpendicular force, so a
    # smaller D lowers it, and the claims are evaluated on the ablated runs by their rules
    (scale, abl), = n['damping_ablation'].items()
    assert float(scale) == ch5.T51_DAMPING_SCALES[-1] < 1.0
    assert abl['fixed_direction']['rms_f_perp_jc_to_ts_n'][0] < \
        0.8 * n['fixed_direction']['rms_f_perp_jc_to_ts_n'][0]
    ids = {c.id for c in claims.CLAIMS if c.experiment == 'table_5_1' and c.quick}
    assert set(abl['claims']) == ids & set(ch5.T51_DAMPING_CLAIMS)
    fx_jc = abl['claims']['table_5_1.fixed_jc_abs']
    assert fx_jc['value'] == abl['fixed_direction']['rms_f_perp_jc_to_ts_n'][0]
    assert fx_jc['passed'] == (0.29 <= fx_jc['value'] <= 1.16)
    assert f'D x {scale}' in check.summary
    # the plant's damping torque -D qdot through J^{+T}, orthogonal to the motion, is of the
    # size of the measured erroneous force (the report's explanation of the absolute forces);
    # it is the plant's D that counts: the ablation's tenth of D cuts it, although that
    # lift is faster
    fd, fm = (n['fixed_direction']['runs'][0][k][0]
              for k in ('rms_fd_perp_jc_ts_n', 'rms_f_perp_jc_ts_n'))
    assert 0.7 * fm < fd < 1.5 * fm, (fd, fm)
    (abl_row,) = abl['fixed_direction']['runs']
    assert abl_row['rms_fd_perp_jc_ts_n'][0] < 0.3 * fd
    assert abl_row['time_to_open_jc_ts_s'][0] < n['fixed_direction']['runs'][0][
        'time_to_open_jc_ts_s'][0]
    saved = json.loads((tmp_path / 'table_5_1.json').read_text())
    assert saved['sma_estimator']['initial_error_deg'] == 45.0
    assert saved['fixed_direction']['runs'][0]['task_specification']['travel'] >= 0.29


def test_fig_5_11_static_erroneous_force_vanishes_once_the_estimate_converges(tmp_path):
    """Fig. 5.11, quick: the 45 deg initial error, (5.9) against trajectory following on the
    LBR (K = 40, kappa = 9 N/s, nu = 0.05 m/s), 0.29 m lift. With (5.9) the force builds up
    at kappa until the drawer moves and the median of the static erroneous force |f_s perp|
    over the second half is under a fifth of its first-half peak (its RMS need not fall:
    the report prints both); the claims are evaluated as written."""
    check, fig, _ = reproduce.run_experiment(_BY_NAME['fig_5_11'], tmp_path, quick=True)
    n = check.numbers
    assert set(n) == {'joint_compliance_45', 'admittance_45', 'misalignment',
                      'damping_ablation'}
    # the cause ablation (ours, no claim): the plant's IFC damping D at a quarter lowers the
    # erroneous force (5.9) leaves in the second half of the lift, the static part too
    (row,) = n.pop('damping_ablation').values()
    low = row['runs']['joint_compliance_45']
    full = n['joint_compliance_45']
    assert low['rms_f_perp_second_half_n'] < 0.8 * full['rms_f_perp_second_half_n']
    assert low['rms_fs_perp_second_half_n'] < 0.8 * full['rms_fs_perp_second_half_n']
    assert row['measured']['jc_vanish'] == pytest.approx(
        low['rms_f_perp_second_half_n'] / low['rms_f_perp_first_half_n'])
    assert 'D x 0.25: jc_vanish' in check.summary
    mis = n.pop('misalignment')
    assert 0 < mis['configurations_over_mu_min'] <= mis['samples']
    assert 0.0 <= mis['share_over_50deg'] <= 1.0 and 0.0 <= mis['max_deg'] <= 90.0
    for v in n.values():
        assert v['travel_m'] >= 0.29
    jc = n['joint_compliance_45']
    assert jc['force_slope_n_s'] == pytest.approx(9.0, rel=0.3)
    assert jc['median_fs_perp_second_half_n'] < 0.2 * jc['max_fs_perp_first_half_n'], jc
    got = {c['id']: c['passed'] for c in check.claims}
    assert set(got) == {'fig_5_11.jc_vanish', 'fig_5_11.jc_below_tf', 'fig_5_11.jc_slope',
                        'fig_5_11.misalignment'}
    assert got['fig_5_11.misalignment'] == (mis['share_over_50deg'] >= 0.1)
    assert got['fig_5_11.jc_vanish'] == (jc['rms_f_perp_second_half_n'] <
                                         0.5 * jc['rms_f_perp_first_half_n'])
    assert fig is not None and fig.exists()
    # the cause of tf_nu_no_relation (full run only): trajectory following's force builds
    # up at nu |K_x d_hat_0| (Sec. 5.3.1's K_p nu); twice nu, twice the predicted slope
    log = ch5._s543_run('admittance', 'drawer_vertical', 45.0, 0.29, duration=60.0)
    model = ch5._tf_slope_model(log, 0.05)
    assert model['measured_n_s'] == pytest.approx(n['admittance_45']['force_slope_n_s'])
    assert model['measured_n_s'] == pytest.approx(model['predicted_n_s'], rel=0.2), model
    assert ch5._tf_slope_model(log, 0.1)['predicted_n_s'] == \
        pytest.approx(2.0 * model['predicted_n_s'])


def test_sec_5_4_worst_misalignment_is_the_largest_angle_over_directions():
    """The closed form (Kantorovich) against a search over directions of dp."""
    rng = np.random.default_rng(3)
    for _ in range(5):
        jac = rng.normal(size=(6, 7))
        mu, worst = ch5._worst_misalignment(jac)
        a = np.linalg.inv(jac @ jac.T)[:3, :3]
        dp = rng.normal(size=(20000, 3))
        f = dp @ a.T
        cos = np.sum(dp * f, axis=1) / np.linalg.norm(dp, axis=1) / np.linalg.norm(f, axis=1)
        assert np.degrees(np.arccos(cos.min())) == pytest.approx(worst, abs=0.5)
        assert mu == pytest.approx(np.sqrt(np.linalg.det(jac @ jac.T)))
    assert ch5._worst_misalignment(np.hstack([np.eye(6), np.zeros((6, 1))]))[1] == \
        pytest.approx(0.0, abs=1e-6)


def test_fig_5_12_horizontal_drawer_new_approach_has_less_erroneous_force(tmp_path):
    """Fig. 5.12: on the horizontal drawer (5.9) pulls 0.25 m with less RMS |f_perp| than
    trajectory following; the claims read the ratios of the static (applied) force of the runs
    (v11)."""
    check, _, _ = reproduce.run_experiment(_BY_NAME['fig_5_12'], tmp_path, quick=True,
                                           figures=False)
    n = check.numbers
    h_jc, h_tf = n['drawer_horizontal/joint_compliance'], n['drawer_horizontal/admittance']
    assert h_jc['travel_m'] >= ch5.F512_TARGET and h_tf['travel_m'] >= 0.25
    assert n['horizontal_ratio'] == pytest.approx(h_jc['rms_f_perp_n'] / h_tf['rms_f_perp_n'])
    assert n['horizontal_ratio'] < 1.0
    got = {c['id']: c['passed'] for c in check.claims}
    static = {}
    for scene in ('horizontal', 'vertical'):
        jc, tf = (n[f'drawer_{scene}/{s}']['rms_fs_perp_n'] for s in
                  ('joint_compliance', 'admittance'))
        static[scene] = jc / tf
        assert n[f'{scene}_ratio_static'] == pytest.approx(static[scene])
    assert got['fig_5_12.jc_below_tf'] == (static['horizontal'] < 1.0)
    assert got['fig_5_12.less_clear'] == (static['horizontal'] > static['vertical'])


def test_fig_5_13_crank_turned_and_faster_exploration_costs_force(tmp_path):
    """Fig. 5.13: (5.9) turns the crank a quarter turn for every radius and kappa; a higher
    kappa gives more erroneous force (R = 0.17 m)."""
    check, _, _ = reproduce.run_experiment(_BY_NAME['fig_5_13'], tmp_path, quick=True,
                                           figures=False)
    n = check.numbers
    assert len(n['runs']) == 5 and n['turned_share'] == 1.0
    assert n['kappa_force_ratio'] > 1.1
    # the claims' estimate error leaves out the initial transient (second half of the turn)
    assert all(0.0 < r['error_angle_at_half_turn_deg'] < 45.0 for r in n['runs'])
    assert n['radius_error_ratio_second_half'] > 0.0


def test_fig_5_10d_pushes_at_half_the_opening_time_and_fig_5_2_filters_the_run():
    """The numbers of the full-run claims of Figs. 5.10d and 5.2 (claims v8)."""
    from experiments import ch5

    n = ch5._fig_5_10d()
    u, d = n['undisturbed'], n['disturbed']
    assert u['push_at_s'] is None and u['time_to_open_s'] is not None
    assert d['push_at_s'] == round(0.5 * u['time_to_open_s'], 3)
    # the push reaches the handle, and the bound's window leaves it (and 0.5 s) out
    assert d['max_force_n'] > u['max_force_n'] + 5.0
    assert d['max_force_outside_push_n'] < d['max_force_n']
    log = ch5._s543_run('joint_compliance', 'drawer_vertical', 45.0, 0.29, duration=60.0)
    f52 = ch5._fig_5_2(log)
    # white noise through a 250-sample mean: 1/sqrt(250) = 0.063 of its RMS (+-30 %)
    assert 0.044 < f52['noise_ratio'] < 0.082, f52
    assert 0.0 < f52['lag_s'] < 1.0 and f52['samples'] == len(log.t)


def test_note_fields_come_from_the_run():
    """Every {field} of a note has a getter in NOTE_FIELDS (numbers come from the run)."""
    import string

    for name, template in report.NOTES.items():
        fields = {f for _, f, _, _ in string.Formatter().parse(template) if f}
        assert fields <= set(report.NOTE_FIELDS.get(name, {})), name
    text = report.note_text('report_6', {'described': {'s2_qdd': -4.0},
                                         'kdl': {'s2_qdd': -0.4444}})
    assert 'qdd = -4 rad/s^2' in text and '(-0.444 rad/s^2)' in text
    assert 'n/a' in report.note_text('table_4_5', {})


def test_table_3_7_runs_of_the_torso_readings_are_valid_stacks():
    """Table 3.7's full-only variants (the other reading, the whole torso clamped, no clamp)
    are stacks the iCub accepts, each clamping the torso joints it names at q_bar = 0."""
    from ifc_spg import RobotModel, TaskStack

    robot = RobotModel.from_config('icub_upper_body')
    base = len(TaskStack.from_file(str(find_config_dir() / 'tasks' /
                                       'table_3_7_icub_wiping_cup_holding.yaml')).build(robot))
    clamped = {}
    for spec in _BY_NAME['table_3_7'].runs:
        if not spec.overrides:
            continue
        (entry,) = spec.overrides['stacks']
        tasks = TaskStack.from_dict(entry['stack']).build(robot)
        clamp = [t for t in tasks if t.name == 'torso_clamp']
        assert len(tasks) == base - (not clamp), spec.label
        clamped[spec.label] = clamp[0] if clamp else None
    assert set(clamped) == {'roll_yaw', 'no_clamp', 'all_torso'}
    assert clamped['no_clamp'] is None
    for name, joints in (('roll_yaw', ('torso_roll', 'torso_yaw')),
                         ('all_torso', ('torso_pitch', 'torso_roll', 'torso_yaw'))):
        task = clamped[name]
        assert tuple(robot.joint_names[i] for i in task.indices) == joints, name
        np.testing.assert_array_equal(task.lower_bound.evaluate(0.0)[0], np.zeros(len(joints)))
