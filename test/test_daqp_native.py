"""The cascade's DAQP solves from C (ifc_spg.cascade._daqp_native) against DAQP's Python module.

The C module calls the daqp module's own compiled DAQP, so the two paths must agree to the
last bit: single level problems (equalities, inequalities, infeasible bounds, zero and
repeated rows) solved through a persistent model, warm-started cascades over random
stacks, and closed loops. Then the fallback where the module is not built or stale.
"""

import importlib
from types import SimpleNamespace

import daqp
import numpy as np
import pytest
from test_hqp import CASES, RHO
from tick_recording import RUNS, run

from ifc_spg import kernels
from ifc_spg.cascade import DaqpCascade
from ifc_spg.cascade import daqp as cdaqp
from ifc_spg.limits import VelocityBox
from ifc_spg.tasks import Level

nat = cdaqp.native
needs_native = pytest.mark.skipif(nat is None, reason=f'not built: {cdaqp.describe()}')


def test_daqp_native_is_built():
    """./run setup builds it (setup.py fetches DAQP's headers; offline it cannot)."""
    assert nat is not None, cdaqp.describe()
    assert nat.DAQP_VERSION == importlib.metadata.version('daqp') and not nat.UNBOUND


def random_problem(rng, n, mA):
    """A QP as the cascade's models see it: H, f, rows, [box; rows] bounds, some rows zero,
    repeated or with equal bounds (equalities), some bounds crossed (infeasible)."""
    L = rng.normal(size=(n, n))
    H = L @ L.T + rng.choice([1e-6, 1e-2, 1.0]) * np.eye(n)
    f = rng.normal(size=n)
    A = rng.normal(size=(mA, n))
    if mA > 2:
        A[rng.integers(mA)] = 0.0  # a zero row
        A[1] = A[0] * rng.choice([1.0, -2.0])  # a repeated row: degenerate
    lo = np.concatenate([-rng.uniform(0.01, 2.0, n), rng.normal(size=mA) - 0.5])
    hi = lo + rng.uniform(0.0, 1.5, n + mA)
    k = rng.random(n + mA)
    hi[k < 0.1] = lo[k < 0.1]  # equal bounds
    lo[(k > 0.9) & (k < 0.95)] = -np.inf
    hi[k > 0.95] = np.inf
    if rng.random() < 0.15:  # crossed bounds: infeasible
        j = rng.integers(n + mA)
        lo[j], hi[j] = 1.0, -1.0
    return H, f, A, hi, lo


def python_model(H, f, A, bu, bl):
    """A model of DAQP's Python module over these arrays, as the cascade sets one up."""
    model = daqp.Model()
    model.setup(H, f, A, bu, bl, np.zeros(bu.size, dtype=np.int32))
    model.settings = {**model.settings, 'primal_tol': 1e-6}
    return model


def python_solve(model, warm, **update):
    """A solve through DAQP's Python module, then the cascade's working-set rule: cold after
    a failure, kept after one iteration, else 1 where the multiplier is not 0, 3 where < 0."""
    model.update(sense=warm, **update)
    x, _, flag, info = model.solve()
    if flag != 1:
        warm[:] = 0
    elif info['iterations'] != 1:
        lam = info['lam']
        warm[:] = np.where(lam != 0.0, np.where(lam < 0.0, 3, 1), 0)
    return x, flag


@needs_native
def test_c_model_equals_the_python_model_on_random_level_problems():
    """Per solve: the same x to the last bit, the same exit flag and working set, over
    sequences of solves on one model (a new H, new rows and bounds, new bounds only)."""
    rng = np.random.default_rng(32)
    flags = set()
    for _ in range(300):
        n, mA = int(rng.integers(1, 18)), int(rng.integers(0, 12))
        H, f, A, bu, bl = random_problem(rng, n, mA)
        m = n + mA
        first = bu.copy(), bl.copy()
        bu[:], bl[:] = np.inf, -np.inf  # set up unbounded, as the cascade's models are
        pmodel = python_model(H, f, A, bu, bl)
        warm_py, warm_c, x_c = (np.zeros(m, np.int32), np.zeros(m, np.int32), np.zeros(n))
        cmodel = nat.Model(H, f, A, bu, bl, warm_c, x_c, 1e-6)
        bu[:], bl[:] = first
        for step in range(4):
            if step:  # change the data in place, as the cascade does
                H2, f2, A2, bu2, bl2 = random_problem(rng, n, mA)
                which = rng.choice(['H', 'A', 'bounds'] if mA else ['H', 'bounds'])
                if which == 'H':
                    H[:], f[:] = H2, f2
                    update, mask = {'H': H, 'f': f}, nat.UPDATE_H | nat.UPDATE_F
                elif which == 'A':
                    A[:], bu[:], bl[:] = A2, bu2, bl2
                    update, mask = {'A': A, 'blower': bl}, nat.UPDATE_A | nat.UPDATE_BOUNDS
                else:
                    bu[:], bl[:] = bu2, bl2
                    update, mask = {'blower': bl}, nat.UPDATE_BOUNDS
            else:
                update, mask = {'H': H, 'blower': bl}, nat.UPDATE_H | nat.UPDATE_BOUNDS
            if rng.random() < 0.3:  # a working set handed in from elsewhere
                warm_py[:] = rng.choice([0, 1, 3], m) * (rng.random(m) < 0.3)
                warm_c[:] = warm_py
            x_py, flag_py = python_solve(pmodel, warm_py, **update)
            flag_c = nat_solve(cmodel, mask)
            flags.add(flag_py)
            assert flag_c == flag_py
            np.testing.assert_array_equal(x_c, x_py)
            np.testing.assert_array_equal(warm_c, warm_py)
            with np.errstate(invalid='ignore', over='ignore'):  # (x is NaN after some failures)
                assert cmodel.finite() == np.isfinite(x_c @ f)
    assert {1, -1} <= flags, flags  # optimal and infeasible problems were among them
    x_c[0], f[0] = np.nan, 1.0
    assert not cmodel.finite()
    x_c[0], f[0] = 1.0, np.inf
    assert not cmodel.finite()


def nat_solve(cmodel, mask):
    return cmodel.solve(int(mask))


def _moved(levels, box, k, rng):
    moved = [Level(lv.name, lv.A + 0.02 * k * np.sin(k + lv.A), lv.lower + 0.01 * k,
                   lv.upper + 0.01 * k, lv.equality) for lv in levels]
    shift = 0.05 * rng.uniform(-1, 1, box.lower.size)
    return moved, VelocityBox(np.minimum(box.lower + shift, -0.01),
                              np.maximum(box.upper + shift, 0.01))


@needs_native
@pytest.mark.parametrize('kern', ['native', 'numpy'])
def test_c_cascade_equals_the_python_cascade_on_random_stacks(kern):
    """Warm-started cascades over random stacks (equality, inequality and mixed levels,
    rows dependent on higher levels, zero columns; some levels infeasible under the higher
    ones): the same solution, slacks, status and working sets, tick after tick."""
    km = kernels.native if kern == 'native' else kernels.reference
    if km is None:
        pytest.skip('the C kernels are not built')
    rng = np.random.default_rng(5)
    statuses, retries = set(), 0
    for n, levels, box in CASES[:80]:
        c = DaqpCascade(n, RHO, kernels=km, daqp_native=True)
        py = DaqpCascade(n, RHO, kernels=km, daqp_native=False)
        assert c.native_daqp is nat and py.native_daqp is None
        for k in range(6):
            moved, mbox = _moved(levels, box, k, rng)
            if k == 3:  # an empty box: every level infeasible (the SPG holds)
                lower = mbox.lower.copy()
                lower[0] = mbox.upper[0] + 0.1
                mbox = VelocityBox(lower, mbox.upper)
            a, b = c.solve(moved, mbox), py.solve(moved, mbox)
            statuses.add(a.status)
            assert (a.status, a.failed_level) == (b.status, b.failed_level)
            np.testing.assert_array_equal(a.qdot_v, b.qdot_v)
            for sa, sb in zip(a.slacks, b.slacks):
                np.testing.assert_array_equal(sa, sb)
            dims = [lv.A.shape[0] for lv in moved]
            eqs = [lv.equality for lv in moved]
            np.testing.assert_array_equal(c.warm_start(dims, eqs), py.warm_start(dims, eqs))
        assert (c.cold_retries, c.relaxed_retries) == (py.cold_retries, py.relaxed_retries)
        retries += c.cold_retries + c.relaxed_retries
    assert {'ok', 'hold'} <= statuses, statuses
    print(f'statuses {sorted(statuses)}, retries {retries}')


@needs_native
def test_c_solves_of_a_degenerate_level_equal_the_python_solves():
    """The degenerate iCub tick of test_hqp (numpy kernels: the locked bands meet the box at
    a vertex; solved after retries): the same retries and solution from C."""
    from test_hqp import _degenerate_icub_levels
    levels, box = _degenerate_icub_levels()
    c = DaqpCascade(17, kernels=kernels.reference, daqp_native=True)
    py = DaqpCascade(17, kernels=kernels.reference, daqp_native=False)
    a, b = c.solve(levels, box), py.solve(levels, box)
    assert a.status == b.status == 'ok' and c.relaxed_retries == py.relaxed_retries >= 1
    assert c.cold_retries == py.cold_retries
    np.testing.assert_array_equal(a.qdot_v, b.qdot_v)


@needs_native
def test_c_solves_retry_cold_like_the_python_solves(monkeypatch):
    """A warm solve that reports 'infeasible' is retried (cold, bands widened) from C as
    through the Python module, and the level model solves again the next tick."""
    rng = np.random.default_rng(9)
    n = 7
    box = VelocityBox(np.full(n, -1.0), np.full(n, 1.0))
    A_eq, A_in = rng.normal(size=(3, n)), rng.normal(size=(2, n))
    target = A_in @ rng.uniform(-0.5, 0.5, n)
    levels = [Level('eq', A_eq, np.ones(3) * 0.1, np.ones(3) * 0.1, True),
              Level('ineq', A_in, target + 0.2, np.full(2, np.inf), False),  # violated at 0
              Level('posture', np.eye(n), np.zeros(n), np.zeros(n), True)]
    c, py = DaqpCascade(n, RHO, daqp_native=True), DaqpCascade(n, RHO, daqp_native=False)
    np.testing.assert_array_equal(c.solve(levels, box).qdot_v, py.solve(levels, box).qdot_v)
    calls = []

    def failing_c(k):
        original = c.solve_native

        def solve(model, mask):  # the k-th solve of the tick reports 'infeasible'
            flag = original(model, mask)
            calls.append(1)
            return -1 if len(calls) == k + 1 else flag
        return solve

    def failing_python(k):
        original = py.solve_model

        def solve(model):
            x, f, flag, info = original(model)
            calls.append(1)
            return (x, f, -1, info) if len(calls) == k + 1 else (x, f, flag, info)
        return solve

    for k in range(3):  # the warm solves of 'eq', 'ineq' (slack model), 'posture'
        calls.clear()
        monkeypatch.setattr(c, 'solve_native', failing_c(k))
        a = c.solve(levels, box)
        assert len(calls) > k
        calls.clear()
        monkeypatch.setattr(py, 'solve_model', failing_python(k))
        b = py.solve(levels, box)
        monkeypatch.undo()
        assert a.status == b.status == 'ok'
        np.testing.assert_array_equal(a.qdot_v, b.qdot_v)
        dims, eqs = [3, 2, n], [True, False, True]
        np.testing.assert_array_equal(c.warm_start(dims, eqs), py.warm_start(dims, eqs))
    assert c.cold_retries == py.cold_retries >= 3
    before = c.cold_retries
    np.testing.assert_array_equal(c.solve(levels, box).qdot_v, py.solve(levels, box).qdot_v)
    assert c.cold_retries == before


@needs_native
@pytest.mark.parametrize('name', sorted(RUNS))
def test_closed_loop_with_c_solves_equals_the_python_solves(name, monkeypatch):
    """The recorded closed loops (test_tick_recorded.py), C kernels: with the C solves and
    with DAQP's Python module, to the last bit."""
    if kernels.native is None:
        pytest.skip('the C kernels are not built')
    with_c = run(name, kernels.native)
    monkeypatch.setattr(cdaqp, 'native', None)  # as if not built: the Python module
    np.testing.assert_array_equal(run(name, kernels.native), with_c)


def test_fallback_where_the_module_is_not_built(monkeypatch):
    """Not built (or stale): cascades call DAQP through its Python module, and say so."""
    real_import = importlib.import_module

    def no_module(name, *args):
        if name == 'ifc_spg.cascade._daqp_native':
            raise ImportError(name)
        return real_import(name, *args)

    monkeypatch.setattr(cdaqp.importlib, 'import_module', no_module)
    monkeypatch.setattr(cdaqp, 'stale', '')
    assert cdaqp._load_native() is None and cdaqp.stale == ''
    monkeypatch.setattr(cdaqp, 'native', None)
    monkeypatch.setattr(cdaqp, '_disabled', False)  # (IFC_SPG_NATIVE=0 would say that)
    assert 'was not built' in cdaqp.describe() and 'Python module' in cdaqp.describe()
    solver = DaqpCascade(7, RHO)
    assert solver.native_daqp is None
    n, levels, box = next(case for case in CASES if case[0] == 7)
    assert solver.solve(levels, box).status == 'ok'


@pytest.mark.parametrize('module, why', [
    (SimpleNamespace(UNBOUND='the daqp module does not export daqp_solve', ABI=cdaqp._ABI,
                     DAQP_VERSION='0.11.0'), 'does not export daqp_solve'),
    (SimpleNamespace(UNBOUND='', ABI=1, DAQP_VERSION='0.11.0'), 'interface 1'),
    (SimpleNamespace(UNBOUND='', ABI=cdaqp._ABI, DAQP_VERSION='0.10.0'), 'DAQP 0.10.0'),
])
def test_a_stale_module_is_not_used(monkeypatch, module, why):
    """Built for another interface or DAQP version, or without DAQP's functions: unused."""
    real_import = importlib.import_module
    monkeypatch.setattr(cdaqp.importlib, 'import_module', lambda name, *args: module
                        if name == 'ifc_spg.cascade._daqp_native' else real_import(name, *args))
    monkeypatch.setattr(cdaqp, 'stale', '')
    assert cdaqp._load_native() is None
    assert why in cdaqp.stale
    monkeypatch.setattr(cdaqp, 'native', None)
    monkeypatch.setattr(cdaqp, '_disabled', False)
    assert 'stale' in cdaqp.describe() and why in cdaqp.describe()


def test_daqp_module_exports_what_the_c_module_binds():
    """The binary of the pinned daqp wheel exports DAQP's C API (the C path's premise)."""
    import ctypes
    lib = ctypes.CDLL(daqp.__file__)
    for name in ('allocate_daqp_settings', 'setup_daqp_main', 'daqp_update_ldp', 'daqp_solve',
                 'free_daqp_workspace', 'free_daqp_ldp'):
        assert hasattr(lib, name), name
