"""Static friction (docs/SPEC.md §10): report scenarios, exact QP vs the report's sampling."""

import numpy as np
import pinocchio as pin
import pytest

from ifc_spg.dynamics import StaticFrictionSolver, VereshchaginSolver, vereshchagin
from ifc_spg.dynamics.models import random_chain_model
from ifc_spg.dynamics.scenarios import external_joint_torques, report_problems
from ifc_spg.dynamics.vereshchagin import KERNELS
from ifc_spg.errors import ParameterError, SolverError


@pytest.fixture(autouse=True, params=KERNELS)
def kernel(request, monkeypatch):
    """Every test here runs on both kernels (solvers built without ``kernel=`` get this one)."""
    monkeypatch.setattr(vereshchagin, 'default_kernel', lambda: request.param)
    return request.param


def _joint_inertia(model):
    M = pin.crba(model, model.createData(), np.zeros(model.nq))
    return float(M[0, 0])


@pytest.mark.parametrize('implemented', [False, True])
def test_report_scenario_1_sticks(implemented):
    prob = report_problems(implemented=implemented)[0]
    fs = prob.friction_solver()
    res = fs.solve(prob.q, prob.qd, prob.tau, **prob.kwargs)
    tau_ext = external_joint_torques(prob.model, prob.q, prob.kwargs['external_wrenches'])
    assert tau_ext == pytest.approx([-5.0])
    assert res.mu == pytest.approx([5.0], abs=1e-8)
    assert res.qdd == pytest.approx([0.0], abs=1e-8)
    assert res.stick.tolist() == [True]
    # without friction the arm would accelerate with -5 Nm / I
    assert res.qdd0 == pytest.approx([-5.0 / _joint_inertia(prob.model)], rel=1e-12)
    ref = fs.solve_sampling(prob.q, prob.qd, prob.tau, samples=21, **prob.kwargs)
    assert ref.mu == pytest.approx([5.0])


@pytest.mark.parametrize('implemented', [False, True])
def test_report_scenario_2_slips(implemented):
    prob = report_problems(implemented=implemented)[1]
    fs = prob.friction_solver()
    res = fs.solve(prob.q, prob.qd, prob.tau, **prob.kwargs)
    tau_ext = external_joint_torques(prob.model, prob.q, prob.kwargs['external_wrenches'])
    inertia = _joint_inertia(prob.model)
    assert abs(res.mu[0]) == pytest.approx(10.0, abs=1e-8)
    assert (prob.tau + res.mu + tau_ext) == pytest.approx([-1.0], abs=1e-8)
    assert res.qdd == pytest.approx([-1.0 / inertia], rel=1e-8)
    assert res.stick.tolist() == [False]
    if implemented:       # the report's number: KDL puts the COM at 1.5 m (I = 2.25 kg m^2)
        assert res.qdd[0] == pytest.approx(-0.44, abs=0.005)


def _random_problem(rng, k):
    n = int(rng.integers(k, k + 4))
    model = random_chain_model(rng, n)
    solver = VereshchaginSolver(model, tip_frame='tip')
    pin.seed(int(rng.integers(2**31 - 1)))  # pinocchio's global generator, from the test's
    q = pin.randomConfiguration(model, -np.pi * np.ones(model.nq), np.pi * np.ones(model.nq))
    qd = rng.normal(size=n)
    rest = rng.choice(n, k, replace=False)
    qd[rest] = 0.0
    f = np.zeros(n)
    f[rest] = rng.uniform(0.2, 4.0, k)
    f[np.setdiff1d(np.arange(n), rest)] = rng.uniform(0.2, 4.0, n - k)   # moving: ignored
    kw = {'base_acceleration': rng.normal(size=6) * 2}
    if rng.random() < 0.5:
        m = int(rng.integers(1, min(n, 3) + 1))
        kw['A_N'] = np.eye(6)[:, rng.choice(6, m, replace=False)]
        kw['b_N'] = rng.normal(size=m)
    tau = rng.normal(size=n) * 3
    return StaticFrictionSolver(solver, f), q, qd, tau, kw, rest


@pytest.mark.parametrize('k', [1, 2, 3])
def test_exact_matches_sampling(k):
    rng = np.random.default_rng(20 + k)
    samples = {1: 41, 2: 21, 3: 9}[k]
    n_stick = 0
    for _ in range({1: 12, 2: 8, 3: 4}[k]):
        fs, q, qd, tau, kw, rest = _random_problem(rng, k)
        ex = fs.solve(q, qd, tau, **kw)
        if ex.result.singular:
            continue
        ref = fs.solve_sampling(q, qd, tau, samples=samples, **kw)
        assert sorted(np.flatnonzero(ex.stationary)) == sorted(rest)
        # the exact optimum is a true maximum of the concave dual ...
        assert ex.gauss >= ref.gauss - 1e-9 * max(1.0, abs(ref.gauss))
        # ... and the grid reaches it up to the resolution: slipping joints sit on the
        # grid (±f), sticking ones are within h/2 of a grid point, g is quadratic with -G
        h = 2 * fs.breakaway[rest] / (samples - 1)
        delta = np.where(ex.stick[rest], h / 2, 0.0)
        bound = 0.5 * np.linalg.eigvalsh(ex.G)[-1] * delta @ delta
        assert ex.gauss - ref.gauss <= bound + 1e-9 * max(1.0, abs(ref.gauss))
        # KKT of the box QP: stick -> q̈_j = 0; slip -> |μ_j| = f_j and q̈_j opposes μ_j
        f = fs.breakaway
        for j in rest:
            if ex.stick[j]:
                assert abs(ex.qdd[j]) < 1e-7
                n_stick += 1
            else:
                assert abs(ex.mu[j]) == pytest.approx(f[j], rel=1e-9)
                assert ex.qdd[j] * np.sign(ex.mu[j]) <= 1e-9
        # moving joints get no static friction
        assert np.all(ex.mu[np.setdiff1d(np.arange(fs.solver.n), rest)] == 0)
    assert n_stick > 0


def test_dual_is_the_concave_quadratic_of_the_characteristic_equation():
    """g(μ) from full solver runs = g(0) − q̈_Θ(0)ᵀμ − ½ μᵀ G μ, G symmetric PSD."""
    rng = np.random.default_rng(30)
    fs, q, qd, tau, kw, rest = _random_problem(rng, 3)
    kw['A_N'], kw['b_N'] = np.eye(6)[:, [1]], np.array([0.4])
    ex = fs.solve(q, qd, tau, **kw)
    joints = np.flatnonzero(ex.stationary)
    g0 = fs.solver.solve(q, qd, tau, gauss=True, **kw).gauss
    assert np.allclose(ex.G, ex.G.T, atol=1e-10)
    assert np.linalg.eigvalsh(ex.G)[0] > -1e-10
    for _ in range(5):
        mu = rng.uniform(-1, 1, joints.size) * fs.breakaway[joints]
        t = tau.copy()
        t[joints] += mu
        g = fs.solver.solve(q, qd, t, gauss=True, **kw).gauss
        model = g0 - ex.qdd0[joints] @ mu - 0.5 * mu @ ex.G @ mu
        assert g == pytest.approx(model, rel=1e-9, abs=1e-9)


def test_qp_solvers_agree():
    rng = np.random.default_rng(31)
    for _ in range(5):
        fs, q, qd, tau, kw, _ = _random_problem(rng, 3)
        a = fs.solve(q, qd, tau, **kw)
        b = StaticFrictionSolver(fs.solver, fs.breakaway, qp_solver='daqp').solve(q, qd, tau,
                                                                                   **kw)
        assert a.gauss == pytest.approx(b.gauss, rel=1e-9, abs=1e-9)
        np.testing.assert_allclose(a.qdd, b.qdd, atol=1e-6)


def test_no_stationary_joint_is_plain_solve():
    rng = np.random.default_rng(32)
    fs, q, qd, tau, kw, _ = _random_problem(rng, 1)
    qd = np.full(fs.solver.n, 0.5)
    ex = fs.solve(q, qd, tau, **kw)
    assert not ex.stationary.any() and np.all(ex.mu == 0)
    np.testing.assert_allclose(ex.qdd, fs.solver.solve(q, qd, tau, **kw).qdd, atol=1e-12)


def test_friction_errors():
    solver = report_problems()[0].solver()
    with pytest.raises(ParameterError, match='breakaway'):
        StaticFrictionSolver(solver, -1.0)
    with pytest.raises(SolverError, match="did you mean 'daqp'"):
        StaticFrictionSolver(solver, 1.0, qp_solver='daqpp')
    with pytest.raises(ParameterError, match='samples'):
        StaticFrictionSolver(solver, 1.0).solve_sampling(np.zeros(1), np.zeros(1), samples=1)
