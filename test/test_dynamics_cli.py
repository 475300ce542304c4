"""``ifc-spg dynamics``: report scenarios, problem files (URDF and MJCF), plots, errors."""

import numpy as np
import pinocchio as pin
import pytest

from benchmarks.dynamics_bench import bench_scaling
from ifc_spg import cli as top_cli
from ifc_spg.cli import dynamics as cli
from ifc_spg.dynamics import StaticFrictionSolver, VereshchaginSolver
from ifc_spg.dynamics.models import random_chain_urdf
from ifc_spg.dynamics.scenarios import load_problem

ARM2_MJCF = ('<mujoco model="arm2"><worldbody><body name="l1">'
             '<joint name="j1" type="hinge" axis="0 0 1"/>'
             '<inertial pos="0.2 0 0" mass="2" diaginertia="0.01 0.03 0.03"/>'
             '<body name="l2" pos="0.4 0 0"><joint name="j2" type="hinge" axis="0 1 0"/>'
             '<inertial pos="0.15 0 0" mass="1" diaginertia="0.004 0.02 0.02"/>'
             '<site name="tool" pos="0.3 0 0"/>'
             '</body></body></worldbody></mujoco>')


def test_scenarios_print_report_numbers(capsys):
    assert cli.main(['--samples', '11']) == 0
    out = capsys.readouterr().out
    assert out.count('mu* (exact QP)  [5.]') == 2          # -5 N: described and KDL arm
    assert out.count('mu* (exact QP)  [10.]') == 2         # -11 N
    assert out.count('resulting torque [-1.]') == 2
    assert 'qdd(mu*)        [-4.]' in out                   # I = 0.25 kg m^2
    assert 'qdd(mu*)        [-0.444444]' in out             # the report's -0.44 rad/s^2


def test_scenarios_plots(tmp_path, capsys):
    assert top_cli.main(['dynamics', 'scenarios', '--plot', str(tmp_path)]) == 0
    pngs = sorted(p.name for p in tmp_path.glob('*.png'))
    assert len(pngs) == 12 and 'scenario2_gauss.png' in pngs
    for p in tmp_path.glob('*.png'):
        assert p.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    capsys.readouterr()


def _write_urdf_problem(tmp_path, rng):
    (tmp_path / 'chain.urdf').write_text(random_chain_urdf(rng, 4))
    (tmp_path / 'problem.yaml').write_text(
        'model: chain.urdf\n'
        'tip_frame: tip\n'
        'q: [0.1, -0.4, 0.3, 0.8]\n'
        'qd: [0.0, 0.5, 0.0, 0.0]\n'
        'tau: [1.0, -2.0, 0.5, 0.0]\n'
        'gravity: [0, 0, -9.81]\n'
        'external_wrenches:\n'
        '  - {frame: tip, force: [0, -5, 1], torque: [0.1, 0, 0]}\n'
        'constraints:\n'
        '  A_N: [[1, 0, 0, 0, 0, 0]]\n'
        '  b_N: [0.2]\n'
        'friction:\n'
        '  breakaway: 2.0\n')
    return tmp_path / 'problem.yaml'


def test_solve_urdf_problem(tmp_path, capsys):
    path = _write_urdf_problem(tmp_path, np.random.default_rng(50))
    assert cli.main(['solve', str(path), '--samples', '5']) == 0
    out = capsys.readouterr().out
    assert 'mu* (exact QP)' in out and 'sampling ref.' in out
    prob = load_problem(str(path))
    got = cli.run_problem(prob, samples=0, out=open('/dev/null', 'w'))
    # independent reference: wrench at 'tip' applied through pinocchio (KKT below)
    model = pin.buildModelFromUrdf(str(tmp_path / 'chain.urdf'))
    q = np.array([0.1, -0.4, 0.3, 0.8])
    qd = np.array([0.0, 0.5, 0.0, 0.0])
    tau = np.array([1.0, -2.0, 0.5, 0.0])
    d = model.createData()
    pin.forwardKinematics(model, d, q)
    pin.updateFramePlacements(model, d)
    fid = model.getFrameId('tip')
    J = pin.computeFrameJacobian(model, d, q, fid, pin.LOCAL_WORLD_ALIGNED)
    wrench = np.array([0, -5, 1, 0.1, 0, 0])
    qdd_free = pin.aba(model, d, q, qd, tau + J.T @ wrench)
    M = pin.crba(model, d, q)
    M = np.triu(M) + np.triu(M, 1).T
    pin.forwardKinematics(model, d, q, qd, np.zeros(4))
    drift = pin.getFrameAcceleration(model, d, fid, pin.LOCAL_WORLD_ALIGNED).vector
    p = d.oMf[fid].translation
    drift[:3] += np.array([0, 0, 9.81])                  # base acceleration -g at the tip
    Jc = J[:1]
    K = np.block([[M, -Jc.T], [Jc, np.zeros((1, 1))]])
    sol = np.linalg.solve(K, np.concatenate((M @ qdd_free, [0.2 - drift[0]])))
    np.testing.assert_allclose(got['plain'].qdd, sol[:4], atol=1e-8)
    assert p.shape == (3,)
    # friction on the three joints at rest (joint 2 moves)
    fr = got['friction']
    assert fr.stationary.tolist() == [True, False, True, True]
    direct = StaticFrictionSolver(VereshchaginSolver(model, tip_frame='tip'), 2.0).solve(
        q, qd, tau, **prob.kwargs)
    np.testing.assert_allclose(fr.qdd, direct.qdd, atol=1e-10)


def test_solve_mjcf_problem(tmp_path, capsys):
    (tmp_path / 'arm2.xml').write_text(ARM2_MJCF)
    # gravity loads joint 2 (about y) with ~1.7 Nm, joint 1 (about z) not at all
    for f2, stick in ((30.0, '[1 1]'), (0.5, '[1 0]')):
        (tmp_path / 'p.yaml').write_text('model: arm2.xml\ntip_frame: tool\nq: [0.2, 0.3]\n'
                                         f'friction: {{breakaway: [1.0, {f2}]}}\n')
        assert cli.main(['solve', str(tmp_path / 'p.yaml'), '--plot', str(tmp_path)]) == 0
        out = capsys.readouterr().out
        assert f'stick           {stick}' in out
    assert (tmp_path / 'p_gauss.png').exists()


@pytest.mark.parametrize('text,match', [
    ('model: nope.urdf\n', 'does not exist'),
    ('model: chain.urdf\nqq: [0]\n', "unknown key 'qq'; did you mean"),
    ('model: chain.urdf\nq: [0, 0]\n', "'q' must have 4 entries"),
    ('model: chain.urdf\nq: [a, b]\n', 'must be a list of numbers'),
    ('model: chain.urdf\ntip_frame: tipp\n', "did you mean 'tip'"),
    ('model: chain.urdf\nexternal_wrenches: [{frame: nowhere, force: [1, 0, 0]}]\n',
     "'nowhere' is not in the model"),
    ('model: chain.urdf\nconstraints: {A_N: [[1, 0, 0]]}\n', 'A_N must be a list'),
    ('model: chain.txt\n', 'must end in .urdf'),
    ('[1, 2\n', 'not valid YAML'),
    ('- just a list\n', 'must be a YAML mapping'),
])
def test_problem_file_errors(tmp_path, capsys, text, match):
    (tmp_path / 'chain.urdf').write_text(random_chain_urdf(np.random.default_rng(51), 4))
    (tmp_path / 'chain.txt').write_text('x')
    (tmp_path / 'bad.yaml').write_text(text)
    assert cli.main(['solve', str(tmp_path / 'bad.yaml')]) == 2
    err = capsys.readouterr().err
    assert 'ifc-spg dynamics: error:' in err and match in err


def test_missing_problem_file(capsys):
    assert cli.main(['solve', '/nonexistent/p.yaml']) == 2
    assert 'does not exist' in capsys.readouterr().err


def test_bench_scaling_smoke():
    res = bench_scaling(np.random.default_rng(0), [2, 4, 8], 20)
    assert res['dof'] == [2, 4, 8] and len(res['median_us']) == 3 and 'r2' in res


@pytest.mark.parametrize('verb', sorted(top_cli.VERBS))
def test_every_ifc_spg_verb_has_a_module_with_main(verb, capsys):
    """Each verb of ``ifc-spg`` dispatches to a module that exists and answers --help."""
    import importlib

    module = importlib.import_module(top_cli.VERBS[verb][0])
    assert callable(module.main)
    try:
        code = top_cli.main([verb, '--help'])
    except SystemExit as exc:  # argparse's --help
        code = exc.code
    assert code == 0
    assert f'ifc-spg {verb}' in capsys.readouterr().out


def test_ifc_spg_usage_lists_every_verb(capsys):
    assert top_cli.main([]) == 2
    out = capsys.readouterr().out
    assert all(f'  {verb} ' in out for verb in top_cli.VERBS) and 'pending' not in out
    assert top_cli.main(['no-such-verb']) == 2
