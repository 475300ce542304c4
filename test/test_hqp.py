"""The strict-priority cascade against a slow reference (docs/SPEC.md §3) and its properties."""

from pathlib import Path

import numpy as np
import pytest
from reference_hqp import reference_cascade

from ifc_spg.cascade import DaqpCascade, ProxsuiteCascade, level_violation, make_solver
from ifc_spg.errors import SolverError
from ifc_spg.kernels import reference
from ifc_spg.limits import VelocityBox
from ifc_spg.tasks import Level

RHO = 0.01


def random_level(rng, n, previous, name):
    m = int(rng.integers(1, min(6, n) + 1))
    A = rng.normal(size=(m, n))
    if previous and rng.random() < 0.3:  # a row dependent on a higher level: degenerate
        prev = previous[int(rng.integers(len(previous)))].A
        A[0] = rng.normal() * prev[int(rng.integers(prev.shape[0]))]
    if rng.random() < 0.2:  # clamped / stiff joints: zero columns
        A[:, rng.random(n) < 0.3] = 0.0
    c = rng.normal(size=m)
    kind = rng.choice(['eq', 'ineq', 'mixed'])
    if kind == 'eq':
        return Level(name, A, c, c.copy(), True)
    lower = c - rng.uniform(0.0, 1.0, m)
    upper = c + rng.uniform(0.0, 1.0, m)
    lower[rng.random(m) < 0.2] = -np.inf
    upper[rng.random(m) < 0.2] = np.inf
    if kind == 'mixed':
        k = rng.random(m) < 0.5
        upper[k] = lower[k] = c[k]
    return Level(name, A, lower, upper, False)


def random_stack(rng, n):
    levels = []
    for i in range(int(rng.integers(2, 7))):
        levels.append(random_level(rng, n, levels, f'L{i}'))
    box = VelocityBox(-rng.uniform(0.05, 2.0, n), rng.uniform(0.05, 2.0, n))
    return levels, box


def cases(count, seed):
    rng = np.random.default_rng(seed)
    return [(n, *random_stack(rng, n)) for n in [7, 17] * (count // 2)]


CASES = cases(240, seed=1)


@pytest.mark.parametrize('solver_cls', [DaqpCascade])
def test_cascade_matches_reference(solver_cls, impl):
    worst = 0.0
    for n, levels, box in CASES:
        solver = solver_cls(n, RHO)
        res = solver.solve(levels, box)
        assert res.status == 'ok'
        ref, ref_slacks = reference_cascade(levels, box.lower, box.upper, RHO)
        err = np.abs(res.qdot_v - ref).max()
        worst = max(worst, err)
        assert err < 1e-6, (n, err)
        for s, r in zip(res.slacks, ref_slacks):
            assert np.abs(s - r).max() < 1e-6
    print(f'{impl}: largest |qdot - reference| over {len(CASES)} stacks: {worst:.2e}')


def test_proxsuite_cascade_close_to_reference():
    worst = []
    for n, levels, box in CASES[:60]:
        res = ProxsuiteCascade(n, RHO).solve(levels, box)
        if res.status != 'ok':
            continue
        ref, _ = reference_cascade(levels, box.lower, box.upper, RHO)
        worst.append(np.abs(res.qdot_v - ref).max())
    # proxsuite (dense ALM) reports some degenerate lower levels infeasible: the reason
    # DAQP is the default. Where it does solve, it must agree with the reference.
    print(f'proxsuite solved {len(worst)}/60 stacks; median |qdot - reference| '
          f'{np.median(worst):.1e}')
    assert len(worst) >= 30
    assert np.median(worst) < 1e-5


def test_lower_levels_never_degrade_higher_levels():
    worst = 0.0
    for n, levels, box in CASES:
        full = DaqpCascade(n, RHO).solve(levels, box).qdot_v
        for j in range(len(levels) - 1):
            upto = DaqpCascade(n, RHO).solve(levels[:j + 1], box).qdot_v
            before = np.linalg.norm(level_violation(levels[j], upto))
            after = np.linalg.norm(level_violation(levels[j], full))
            worst = max(worst, after - before)
            assert after <= before + 1e-6, (j, before, after)
    print(f'largest strict-priority violation: {worst:.2e}')


def test_box_is_never_violated_by_the_solver():
    for n, levels, box in CASES:
        res = DaqpCascade(n, RHO).solve(levels, box)
        assert np.all(res.qdot_v >= box.lower) and np.all(res.qdot_v <= box.upper)


def feasible_stack(rng, n):
    """Levels that a common qdot_true inside the box satisfies."""
    box = VelocityBox(-rng.uniform(0.5, 2.0, n), rng.uniform(0.5, 2.0, n))
    q_true = rng.uniform(0.5 * box.lower, 0.5 * box.upper)
    levels = []
    budget = n
    for i in range(int(rng.integers(2, 5))):
        m = int(rng.integers(1, 4))
        A = rng.normal(size=(m, n))
        a = A @ q_true
        if rng.random() < 0.5 and budget >= m:
            budget -= m
            levels.append(Level(f'L{i}', A, a, a.copy(), True))
        else:
            levels.append(Level(f'L{i}', A, a - rng.uniform(0, 1, m), a + rng.uniform(0, 1, m),
                                False))
    return levels, box


@pytest.mark.parametrize('n', [7, 17])
def test_feasible_levels_have_zero_slack(n):
    rng = np.random.default_rng(7 + n)
    for _ in range(100):
        levels, box = feasible_stack(rng, n)
        res = DaqpCascade(n, rho=1e-9).solve(levels, box)
        assert res.status == 'ok'
        for lev, s in zip(levels, res.slacks):
            assert np.abs(s).max() < 1e-6
            assert np.abs(level_violation(lev, res.qdot_v)).max() < 1e-6


def test_infeasible_level_gets_least_squares_compromise():
    # two contradicting equality levels on the same row: the second keeps the first's value
    A = np.array([[1.0, 1.0, 0.0]])
    lv1 = Level('a', A, np.array([1.0]), np.array([1.0]), True)
    lv2 = Level('b', A, np.array([3.0]), np.array([3.0]), True)
    box = VelocityBox(np.full(3, -10.0), np.full(3, 10.0))
    res = DaqpCascade(3, rho=1e-9).solve([lv1, lv2], box)
    assert abs(A @ res.qdot_v - 1.0) < 1e-6
    assert abs(res.slacks[1][0] - (-2.0)) < 1e-6
    # with a box that makes level 1 infeasible, its slack is the least-squares residual
    tight = VelocityBox(np.full(3, -0.2), np.full(3, 0.2))
    res = DaqpCascade(3, rho=1e-9).solve([lv1], tight)
    assert abs(A @ res.qdot_v - 0.4) < 1e-6
    assert abs(res.slacks[0][0] + 0.6) < 1e-6


@pytest.mark.parametrize('n,m', [(7, 6), (7, 3), (17, 6)])
def test_single_equality_task_is_the_pseudo_inverse(n, m):
    """(3.29): with rho -> 0 and no active bounds, qdot = A^+ beta."""
    rng = np.random.default_rng(n * 10 + m)
    for _ in range(20):
        A = rng.normal(size=(m, n))
        beta = rng.normal(size=m)
        box = VelocityBox(np.full(n, -1e3), np.full(n, 1e3))
        res = DaqpCascade(n, rho=1e-10).solve([Level('t', A, beta, beta, True)], box)
        np.testing.assert_allclose(res.qdot_v, np.linalg.pinv(A) @ beta, atol=1e-6)


def test_failed_level_falls_back_to_higher_levels(monkeypatch):
    n = 4
    levels = [Level('a', np.eye(n)[:2], np.ones(2), np.ones(2), True),
              Level('b', np.eye(n)[2:], np.ones(2), np.ones(2), True)]
    box = VelocityBox(np.full(n, -5.0), np.full(n, 5.0))
    solver = DaqpCascade(n)
    good = solver.solve(levels[:1], box).qdot_v
    original_model, original_solve = solver.solve_model, solver.solve_qp
    calls = []

    def failing_model(model):  # every QP after the first level's returns garbage
        calls.append(1)
        x, f, flag, info = original_model(model)
        return (x, f, flag, info) if len(calls) == 1 else (x * np.nan, f, 1, info)

    def failing_solve(*args, **kw):  # the retry in the slack form too
        x, f, flag, info = original_solve(*args, **kw)
        return x * np.nan, f, 1, info

    monkeypatch.setattr(solver, 'solve_model', failing_model)
    monkeypatch.setattr(solver, 'solve_qp', failing_solve)
    res = solver.solve(levels, box)
    assert res.status == 'fallback' and res.failed_level == 1
    np.testing.assert_allclose(res.qdot_v, good)
    assert np.all(np.isfinite(res.qdot_v))


def test_unknown_solver_names_the_choices():
    with pytest.raises(SolverError,
                       match="did you mean 'daqp'.*available: daqp, proxsuite, nullspace"):
        make_solver('daqpp', 7)


def test_warm_started_solves_match_the_reference(impl):
    """One solver over a slowly varying stack (as from tick to tick): each level's DAQP model
    starts from its last working set, and must still give the reference solution."""
    rng = np.random.default_rng(3)
    worst = 0.0
    for n, levels, box in CASES[:40]:
        solver = DaqpCascade(n, RHO)
        for k in range(8):
            moved = [Level(lv.name, lv.A + 0.02 * k * np.sin(k + lv.A), lv.lower + 0.01 * k,
                           lv.upper + 0.01 * k, lv.equality) for lv in levels]
            shift = 0.05 * rng.uniform(-1, 1, n)
            mbox = VelocityBox(np.minimum(box.lower + shift, -0.01),
                               np.maximum(box.upper + shift, 0.01))
            res = solver.solve(moved, mbox)
            assert res.status == 'ok'
            ref, ref_slacks = reference_cascade(moved, mbox.lower, mbox.upper, RHO)
            err = np.abs(res.qdot_v - ref).max()
            worst = max(worst, err)
            # DAQP works to its 1e-6 primal tolerance, the reference to 1e-9; over these
            # perturbed 17-DoF stacks the two differ by up to ~1.4e-6
            assert err < 2e-6, (n, k, err)
            for lv, s, r in zip(moved, res.slacks, ref_slacks):
                # DAQP's tolerance (1e-6) applies to unit rows: 1e-6 |row| in task units
                tol = 1e-6 * (1.0 + np.linalg.norm(lv.A, axis=1))
                assert np.all(np.abs(s - r) < tol), (np.abs(s - r), tol)
    print(f'{impl}: largest |qdot - reference| over warm-started solves: {worst:.2e}')


def _degenerate_icub_levels():
    """A tick of the iCub Table 3.7 stack (closed loop, tick 3383) where l_orientation is
    degenerate: its locked higher rows meet the acceleration box at a vertex."""
    d = np.load(Path(__file__).parent / 'data' / 'degenerate_icub_levels.npz')
    levels = [Level(str(d['names'][k]), d[f'A{k}'], d[f'lower{k}'], d[f'upper{k}'],
                    bool(d[f'eq{k}'])) for k in range(len(d['names']))]
    return levels, VelocityBox(d['box_lower'], d['box_upper'])


def test_degenerate_level_is_solved_with_bands_widened_to_the_solver_tolerance():
    levels, box = _degenerate_icub_levels()
    # The tick was captured with the numpy row arithmetic; the C kernels round differently
    # and miss this vertex (solved without a retry, checked below), so take the numpy path.
    def numpy_solver():
        return DaqpCascade(17, kernels=reference)

    solver = numpy_solver()
    res = solver.solve(levels, box)
    assert res.status == 'ok' and solver.relaxed_retries >= 1
    assert DaqpCascade(17).solve(levels, box).status == 'ok'
    assert np.all(res.qdot_v >= box.lower) and np.all(res.qdot_v <= box.upper)
    # no higher level gives up more than the widening (1e-6 per unit row) to a lower one
    for j in range(len(levels) - 1):
        upto = numpy_solver().solve(levels[:j + 1], box)
        assert upto.status == 'ok'
        lv = levels[j]
        moved = np.abs(lv.A @ res.qdot_v - lv.A @ upto.qdot_v)
        assert np.all(moved <= 3e-6 * (1.0 + np.linalg.norm(lv.A, axis=1))), (lv.name, moved)


def test_failed_warm_solve_retries_cold_and_the_level_model_recovers(monkeypatch):
    """A level model whose warm solve fails is retried (cold, bands widened) within the
    tick; the model forgets its working set and solves the next tick again."""
    rng = np.random.default_rng(9)
    n = 7
    box = VelocityBox(np.full(n, -1.0), np.full(n, 1.0))
    A_eq, A_in = rng.normal(size=(3, n)), rng.normal(size=(2, n))
    target = A_in @ rng.uniform(-0.5, 0.5, n)
    levels = [Level('eq', A_eq, np.ones(3) * 0.1, np.ones(3) * 0.1, True),
              Level('ineq', A_in, target + 0.2, np.full(2, np.inf), False),  # violated at 0
              Level('posture', np.eye(n), np.zeros(n), np.zeros(n), True)]
    ref, _ = reference_cascade(levels, box.lower, box.upper, RHO)
    solver = DaqpCascade(n, RHO)
    np.testing.assert_allclose(solver.solve(levels, box).qdot_v, ref, atol=1e-6)
    original = solver.solve_model
    calls = []

    def fail_call(k):
        def solve(model):  # the k-th model solve of the tick reports 'infeasible'
            x, f, flag, info = original(model)
            calls.append(1)
            return (x, f, -1, info) if len(calls) == k + 1 else (x, f, flag, info)
        return solve

    for k in range(3):  # the warm solves of 'eq', 'ineq' (slack model), 'posture'
        calls.clear()
        monkeypatch.setattr(solver, 'solve_model', fail_call(k))
        res = solver.solve(levels, box)
        assert res.status == 'ok' and len(calls) > k
        np.testing.assert_allclose(res.qdot_v, ref, atol=1e-6)
    monkeypatch.setattr(solver, 'solve_model', original)
    before = solver.cold_retries
    np.testing.assert_allclose(solver.solve(levels, box).qdot_v, ref, atol=1e-6)
    assert solver.cold_retries == before
