"""Popov-Vereshchagin solver against pinocchio.

ABA (no constraints) and the Gauss-principle KKT solve (constraints), on iiwa arms and
random chains.
"""

import numpy as np
import pinocchio as pin
import pytest

from ifc_spg.dynamics import VereshchaginSolver, vereshchagin
from ifc_spg.dynamics.models import iiwa_like_model, planar_arm, random_chain_model
from ifc_spg.dynamics.vereshchagin import KERNELS
from ifc_spg.errors import ModelError, ParameterError, UnknownFrame


@pytest.fixture(autouse=True, params=KERNELS)
def kernel(request, monkeypatch):
    """Every test here runs on both kernels (solvers built without ``kernel=`` get this one)."""
    monkeypatch.setattr(vereshchagin, 'default_kernel', lambda: request.param)
    return request.param


def _fext_local(model, data, q, wrenches):
    """Solver wrenches (base axes, at joint origins) -> pinocchio's LOCAL joint forces."""
    pin.forwardKinematics(model, data, q)
    fl = pin.StdVec_Force()
    fl.append(pin.Force.Zero())
    for i, w in enumerate(wrenches):
        R = data.oMi[i + 1].rotation
        fl.append(pin.Force(R.T @ w[:3], R.T @ w[3:]))
    return fl


def _random_state(rng, model):
    n = model.nv
    # randomConfiguration draws from pinocchio's global generator: seeded from ``rng``, the
    # state is the test's own (it depended on what ran before: one test's check of a
    # minimum |w x v| failed after test_dynamics_native in the same process)
    pin.seed(int(rng.integers(2**31 - 1)))
    return (pin.randomConfiguration(model, -np.pi * np.ones(model.nq), np.pi * np.ones(model.nq)),
            rng.normal(size=n) * 2, rng.normal(size=n) * 5)


def _check_against_aba(model, rng, states, tip_frame=None):
    solver = VereshchaginSolver(model, tip_frame=tip_frame)
    worst = 0.0
    for k in range(states):
        q, qd, tau = _random_state(rng, model)
        ref_model = model.copy()
        kwargs = {}
        if k % 2:                      # random base acceleration (angular too) and wrenches
            a0 = rng.normal(size=6) * 3
            ref_model.gravity = pin.Motion(-a0)
            kwargs['base_acceleration'] = a0
            kwargs['external_wrenches'] = rng.normal(size=(model.nv, 6))
        ref_data = ref_model.createData()
        if 'external_wrenches' in kwargs:
            fl = _fext_local(ref_model, ref_data, q, kwargs['external_wrenches'])
            ref = pin.aba(ref_model, ref_data, q, qd, tau, fl)
        else:
            ref = pin.aba(ref_model, ref_data, q, qd, tau)
        res = solver.solve(q, qd, tau, **kwargs)
        np.testing.assert_allclose(res.qdd, ref, rtol=1e-9, atol=1e-9)
        worst = max(worst, float(np.max(np.abs(res.qdd - ref))))
        assert res.nu.shape == (0,) and not res.singular
    return worst


def test_no_constraints_equals_aba_iiwa():
    model = iiwa_like_model()
    assert model.nv == 7 and np.all(model.armature > 0)
    _check_against_aba(model, np.random.default_rng(1), 500, tip_frame='tool')


def test_no_constraints_equals_aba_robot_model_iiwa():
    """The shipped ``lbr_iiwa14`` configuration (RobotModel passed directly)."""
    from ifc_spg import RobotModel
    robot = RobotModel.from_config('lbr_iiwa14')
    assert VereshchaginSolver(robot, tip_frame=robot.frames['tool']).n == 7
    _check_against_aba(robot.model, np.random.default_rng(4), 500,
                       tip_frame=robot.frames['tool'])


def test_no_constraints_equals_aba_random_chains():
    rng = np.random.default_rng(2)
    kinds = set()
    for n in range(2, 31):
        model = random_chain_model(rng, n)
        kinds.update(j.shortname() for j in model.joints[1:])
        _check_against_aba(model, rng, 20, tip_frame='tip')
    # the random chains exercise aligned/unaligned revolute and prismatic joints
    assert {'JointModelRevoluteUnaligned', 'JointModelPrismaticUnaligned'} <= kinds
    assert kinds & {'JointModelRX', 'JointModelRY', 'JointModelRZ'}


def test_fixed_joints_are_folded():
    """The iiwa tool hangs on two fixed joints: its mass is part of segment 7."""
    model = iiwa_like_model(tool_mass=0.3)
    solver = VereshchaginSolver(model, tip_frame='tool')
    assert solver.n == 7
    assert solver.chain.mass[-1] == pytest.approx(1.2 + 0.3)
    np.testing.assert_allclose(solver.chain.tip_placement[:3, 3], [0, 0, 0.145], atol=1e-12)


def test_continuous_joint():
    pin.seed(3)  # pinocchio's global generator (Inertia.Random): the test's own model
    model = pin.Model()
    j1 = model.addJoint(0, pin.JointModelRUBZ(), pin.SE3.Identity(), 'j1')
    model.appendBodyToJoint(j1, pin.Inertia.Random(), pin.SE3.Identity())
    j2 = model.addJoint(j1, pin.JointModelRY(), pin.SE3(np.eye(3), np.array([0.3, 0, 0])), 'j2')
    model.appendBodyToJoint(j2, pin.Inertia.Random(), pin.SE3.Identity())
    model.armature[:] = [0.1, 0.2]
    _check_against_aba(model, np.random.default_rng(3), 20)


def _gauss_reference(model, fid, q, qd, tau, a0, wrenches, A, b):
    """Argmin ½(q̈−q̈_free)ᵀM(q̈−q̈_free) s.t. Aᵀ(J q̈ + J̇q̇ + Ẍ_0 at the tip) = b (KKT)."""
    m = model.copy()
    m.gravity = pin.Motion(-a0)
    d = m.createData()
    fl = _fext_local(m, d, q, wrenches)
    qdd_free = pin.aba(m, d, q, qd, tau, fl)
    M = pin.crba(m, d, q)
    M = np.triu(M) + np.triu(M, 1).T
    pin.computeJointJacobians(m, d, q)
    pin.forwardKinematics(m, d, q, qd, np.zeros(m.nv))
    pin.updateFramePlacements(m, d)
    J = pin.getFrameJacobian(m, d, fid, pin.LOCAL_WORLD_ALIGNED)
    # spatial (KDL) drift J̇q̇: pinocchio's frame acceleration with q̈ = 0 (no gravity in it)
    drift = pin.getFrameAcceleration(m, d, fid, pin.LOCAL_WORLD_ALIGNED).vector
    p = d.oMf[fid].translation
    a0_tip = np.concatenate((a0[:3] + np.cross(a0[3:], p), a0[3:]))
    Jc = A.T @ J
    sv = np.linalg.svd(Jc, compute_uv=False)
    if sv[-1] < 1e-6 * sv[0]:
        return None                  # constraints (nearly) dependent: see the singular tests
    k = A.shape[1]
    K = np.block([[M, -Jc.T], [Jc, np.zeros((k, k))]])
    sol = np.linalg.solve(K, np.concatenate((M @ qdd_free, b - A.T @ (drift + a0_tip))))
    return sol[:m.nv], sol[m.nv:], m, d, fl


@pytest.mark.parametrize('seed', range(6))
def test_constraints_equal_gauss_kkt(seed):
    rng = np.random.default_rng(100 + seed)
    cases = 0
    for n in (2, 3, 5, 7, 9, 12):
        model = random_chain_model(rng, n)
        fid = model.getFrameId('tip')
        solver = VereshchaginSolver(model, tip_frame='tip')
        for _ in range(5):
            q, qd, tau = _random_state(rng, model)
            a0 = rng.normal(size=6) * 3
            W = rng.normal(size=(n, 6))
            m = int(rng.integers(1, min(n, 6) + 1))
            if rng.random() < 0.5:
                A = np.eye(6)[:, rng.choice(6, m, replace=False)]    # unit axes as the report
            else:
                A = np.linalg.qr(rng.normal(size=(6, m)))[0]
            b = rng.normal(size=m)
            res = solver.solve(q, qd, tau, base_acceleration=a0, external_wrenches=W,
                               A_N=A, b_N=b)
            ref = _gauss_reference(model, fid, q, qd, tau, a0, W, A, b)
            if ref is None:
                assert res.singular or res.rank < m or np.linalg.cond(res.coupling) > 1e5
                continue
            qdd, lam, m_ref, d_ref, fl = ref
            cases += 1
            assert not res.singular and res.rank == m
            np.testing.assert_allclose(res.qdd, qdd, rtol=1e-8, atol=1e-8)
            # the constraint wrench on the last segment is -A nu (KDL sign)
            np.testing.assert_allclose(-res.nu, lam, rtol=1e-7, atol=1e-8)
            np.testing.assert_allclose(A.T @ res.tip_acceleration, b, atol=1e-8)
            np.testing.assert_allclose(res.constraint_residual, 0, atol=1e-8)
            # control torques through ABA (no constraint) reproduce q̈
            np.testing.assert_allclose(pin.aba(m_ref, d_ref, q, qd, res.tau_control, fl),
                                       res.qdd, rtol=1e-8, atol=1e-8)
            # segment accelerations = pinocchio's spatial accelerations + base acceleration
            pin.forwardKinematics(m_ref, d_ref, q, qd, res.qdd)
            for i in range(n):
                oMi = d_ref.oMi[i + 1]
                a_lwa = np.concatenate((oMi.rotation @ d_ref.a[i + 1].linear,
                                        oMi.rotation @ d_ref.a[i + 1].angular))
                p = oMi.translation
                a_lwa[:3] += a0[:3] + np.cross(a0[3:], p)
                a_lwa[3:] += a0[3:]
                np.testing.assert_allclose(res.segment_accelerations[i], a_lwa, rtol=1e-8,
                                           atol=1e-8)
    assert cases >= 20


def test_spatial_vs_classical_acceleration():
    """Ẍ_N is the spatial acceleration: classical = spatial + [ω × v; 0]."""
    rng = np.random.default_rng(7)
    model = iiwa_like_model()
    fid = model.getFrameId('tool')
    solver = VereshchaginSolver(model, tip_frame='tool')
    q, qd, tau = _random_state(rng, model)
    res = solver.solve(q, qd, tau, base_acceleration=np.zeros(6))
    d = model.createData()
    pin.forwardKinematics(model, d, q, qd, res.qdd)
    pin.updateFramePlacements(model, d)
    v = pin.getFrameVelocity(model, d, fid, pin.LOCAL_WORLD_ALIGNED)
    classical = pin.getFrameClassicalAcceleration(model, d, fid, pin.LOCAL_WORLD_ALIGNED)
    np.testing.assert_allclose(classical.linear,
                               res.tip_acceleration[:3] + np.cross(v.angular, v.linear),
                               atol=1e-9)
    assert np.linalg.norm(np.cross(v.angular, v.linear)) > 0.1   # the difference matters


def test_sensitivity_columns_are_unit_torque_responses():
    rng = np.random.default_rng(8)
    model = random_chain_model(rng, 6)
    solver = VereshchaginSolver(model, tip_frame='tip')
    q, qd, tau = _random_state(rng, model)
    kw = {'A_N': np.eye(6)[:, :2], 'b_N': np.array([0.3, -0.2])}
    joints = [1, 4, 5]
    base, G, combine = solver.solve_with_sensitivity(q, qd, tau, joints=joints, **kw)
    ref0 = solver.solve(q, qd, tau, **kw)
    np.testing.assert_allclose(base.qdd, ref0.qdd, atol=1e-10)
    for k, j in enumerate(joints):
        t = tau.copy()
        t[j] += 1.0
        np.testing.assert_allclose(G[:, k], solver.solve(q, qd, t, **kw).qdd - ref0.qdd,
                                   atol=1e-9)
    mu = rng.normal(size=3)
    t = tau.copy()
    t[joints] += mu
    full = solver.solve(q, qd, t, gauss=True, **kw)
    comb = combine(mu, gauss=True)
    for name in ('qdd', 'nu', 'tau_control', 'segment_accelerations', 'tip_acceleration'):
        np.testing.assert_allclose(getattr(comb, name), getattr(full, name), atol=1e-9)
    assert comb.gauss == pytest.approx(full.gauss, abs=1e-9)


def test_gauss_function_value():
    """Z(q̈) − Z(q̈_free) = ½ (q̈ − q̈_free)ᵀ M (q̈ − q̈_free) (Z is the Gauss function)."""
    rng = np.random.default_rng(9)
    model = random_chain_model(rng, 5)
    solver = VereshchaginSolver(model, tip_frame='tip')
    q, qd, tau = _random_state(rng, model)
    kw = {'base_acceleration': rng.normal(size=6), 'external_wrenches': rng.normal(size=(5, 6))}
    free = solver.solve(q, qd, tau, gauss=True, **kw)
    con = solver.solve(q, qd, tau, gauss=True, A_N=np.eye(6)[:, [0, 2, 4]],
                       b_N=rng.normal(size=3), **kw)
    M = pin.crba(model, model.createData(), q)
    M = np.triu(M) + np.triu(M, 1).T
    dq = con.qdd - free.qdd
    assert con.gauss - free.gauss == pytest.approx(0.5 * dq @ M @ dq, rel=1e-9)


def test_rank_deficient_more_constraints_than_dof():
    rng = np.random.default_rng(10)
    model = planar_arm(3, armature=0.05)
    fid = model.getFrameId('tip')
    solver = VereshchaginSolver(model, tip_frame='tip')
    q, qd, tau = np.array([0.3, -0.7, 0.9]), np.array([0.5, -0.2, 0.1]), rng.normal(size=3)
    A, b = np.eye(6), rng.normal(size=6)
    res = solver.solve(q, qd, tau, base_acceleration=np.zeros(6), A_N=A, b_N=b)
    assert res.singular and res.rank == 3
    assert np.all(np.isfinite(res.qdd)) and np.all(np.isfinite(res.nu))
    # limit of the damped solution: least-squares constraint satisfaction (pseudo-inverse)
    d = model.createData()
    M = pin.crba(model, d, q)
    M = np.triu(M) + np.triu(M, 1).T
    qdd_free = pin.aba(model, d, q, qd, tau)
    pin.computeJointJacobians(model, d, q)
    pin.forwardKinematics(model, d, q, qd, np.zeros(3))
    pin.updateFramePlacements(model, d)
    J = pin.getFrameJacobian(model, d, fid, pin.LOCAL_WORLD_ALIGNED)
    drift = pin.getFrameAcceleration(model, d, fid, pin.LOCAL_WORLD_ALIGNED).vector
    Minv_JT = np.linalg.solve(M, J.T @ A)
    Lam_inv = A.T @ J @ Minv_JT
    lam = np.linalg.pinv(Lam_inv, rcond=1e-9) @ (b - A.T @ (J @ qdd_free + drift))
    np.testing.assert_allclose(res.qdd, qdd_free + Minv_JT @ lam, atol=1e-5)
    assert np.linalg.norm(res.constraint_residual) > 1e-3      # infeasible: reported


def test_rank_deficient_singular_configuration():
    """Stretched planar arm: no tip acceleration along the arm is possible from q̈."""
    model = planar_arm(2)
    solver = VereshchaginSolver(model, tip_frame='tip')
    res = solver.solve(np.zeros(2), np.zeros(2), np.zeros(2), base_acceleration=np.zeros(6),
                       A_N=np.eye(6)[:, [0, 1]], b_N=np.array([1.0, 0.0]))
    assert res.singular and res.rank == 1
    assert np.all(np.isfinite(res.qdd))
    ok = solver.solve(np.array([0.0, 0.5]), np.zeros(2), np.zeros(2),
                      base_acceleration=np.zeros(6), A_N=np.eye(6)[:, [0, 1]],
                      b_N=np.array([1.0, 0.0]))
    assert not ok.singular and ok.rank == 2


def test_input_errors():
    model = iiwa_like_model()
    solver = VereshchaginSolver(model)
    q = np.zeros(7)
    with pytest.raises(ParameterError, match='qd must have shape'):
        solver.solve(q, np.zeros(6))
    with pytest.raises(ModelError, match='q must have shape'):
        solver.solve(np.zeros(3), np.zeros(7))
    with pytest.raises(ParameterError, match='A_N must have shape'):
        solver.solve(q, np.zeros(7), A_N=np.zeros((3, 2)))
    with pytest.raises(ParameterError, match='b_N must have shape'):
        solver.solve(q, np.zeros(7), A_N=np.eye(6)[:, :2], b_N=np.zeros(3))
    with pytest.raises(ParameterError, match='finite'):
        solver.solve(q, np.full(7, np.nan))
    with pytest.raises(UnknownFrame, match="did you mean 'tool'"):
        VereshchaginSolver(model, tip_frame='tol')
    with pytest.raises(UnknownFrame, match='not to the last joint'):
        VereshchaginSolver(model, tip_frame='iiwa_link_3')


def test_model_errors():
    tree = pin.Model()
    a = tree.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), 'a')
    tree.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), 'b')
    tree.appendBodyToJoint(a, pin.Inertia.Random(), pin.SE3.Identity())
    with pytest.raises(ModelError, match='tree, not a serial chain'):
        VereshchaginSolver(tree)
    sph = pin.Model()
    sph.addJoint(0, pin.JointModelSpherical(), pin.SE3.Identity(), 'ball')
    with pytest.raises(ModelError, match='JointModelSpherical'):
        VereshchaginSolver(sph)
    with pytest.raises(ModelError, match='no joints'):
        VereshchaginSolver(pin.Model())
