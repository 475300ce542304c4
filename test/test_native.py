"""The C kernels of the 2 ms path (ifc_spg.kernels._native) against their numpy reference code.

Every kernel is compared with the numpy code it replaces (still in the package, used where
the module is not built) on seeded random inputs, including NaN / inf bounds, stiff joints
and boxes that do not intersect; then whole closed-loop runs with and without the kernels.
"""

import os

import numpy as np
import pytest

from ifc_spg import RobotModel
from ifc_spg import kernels as native
from ifc_spg.cascade.daqp import _accept, _lock_if_satisfied, _stack_rows, _Workspace
from ifc_spg.kernels import _native as nat  # the kernels, whatever IFC_SPG_NATIVE selects
from ifc_spg.limits import JointVelocityLimits, VelocityBox
from ifc_spg.offline.plants import JointImpedancePlant
from ifc_spg.pspm import EnergyTanks, PspmConfig
from ifc_spg.spg import SetPointGenerator
from ifc_spg.tasks import Level
from ifc_spg.tools.bench import icub_stack, lbr_stack


def test_native_kernels_are_built():
    """The install builds the kernels (./run setup); IFC_SPG_NATIVE=0 opts out explicitly."""
    if os.environ.get('IFC_SPG_NATIVE', '1').strip() == '0':
        assert native.module is None and 'IFC_SPG_NATIVE=0' in native.describe()
    else:
        assert native.module is nat, native.describe()


def random_levels(rng, n):
    levels = []
    for i in range(int(rng.integers(1, 6))):
        m = int(rng.integers(1, 7))
        A = rng.normal(size=(m, n)) * 10.0 ** rng.uniform(-2, 2.5)
        if rng.random() < 0.3:
            A[0] = 0.0  # an all-zero row (a clamped joint's task row)
        lo = rng.normal(size=m)
        hi = lo + rng.uniform(0, 1, m)
        lo[rng.random(m) < 0.2] = -np.inf
        hi[rng.random(m) < 0.2] = np.inf
        if rng.random() < 0.3:
            A = np.asfortranarray(A)  # any layout is accepted (converted)
        levels.append(Level(f'L{i}', A, lo, hi, False))
    return levels


@pytest.mark.parametrize('n', [7, 17])
def test_stack_rows_matches_numpy(n):
    rng = np.random.default_rng(n)
    for _ in range(200):
        levels = random_levels(rng, n)
        R = sum(lv.A.shape[0] for lv in levels)
        a, b = _Workspace(n, R, 0.01, {}), _Workspace(n, R, 0.01, {})
        _stack_rows(levels, [lv.A.shape[0] for lv in levels], a, 1e-9)
        nat.stack_rows(levels, b.A, b.orig_lo, b.orig_hi, b.norm, b.A_unit, b.band, 1e-9)
        for name in ('A', 'orig_lo', 'orig_hi'):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        for name in ('norm', 'A_unit', 'band'):
            np.testing.assert_allclose(getattr(b, name), getattr(a, name), rtol=1e-14,
                                       atol=1e-300)


def random_workspace(rng):
    """A workspace holding random levels (7 or 17 joints); returns ``(n, levels, R, ws)``."""
    n = int(rng.choice([7, 17]))
    levels = random_levels(rng, n)
    R = sum(lv.A.shape[0] for lv in levels)
    ws = _Workspace(n, R, 0.01, {})
    _stack_rows(levels, [lv.A.shape[0] for lv in levels], ws, 1e-9)
    return n, levels, R, ws


def test_normal_form_accept_and_lock_match_numpy():
    rng = np.random.default_rng(5)
    for _ in range(300):
        n, levels, R, ws = random_workspace(rng)
        ws.bl[:n] = -rng.uniform(0.01, 1, n)
        ws.bu[:n] = rng.uniform(0.01, 1, n)
        start = int(rng.integers(0, R - levels[-1].A.shape[0] + 1))
        end = start + int(rng.integers(1, R - start + 1))
        sl = slice(start, end)
        A_i, beta = ws.A[sl], ws.orig_lo[sl]
        # H = rho I + A^T A, f = -A^T beta (the equality level's cost)
        H, f = np.zeros((n, n)), np.zeros(n)
        target = np.where(np.isfinite(beta), beta, 0.5)  # an equality level's are finite
        nat.normal_form(A_i, target, 0.01, H, f)
        np.testing.assert_allclose(H, 0.01 * np.eye(n) + A_i.T @ A_i, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(f, -target @ A_i, rtol=1e-12, atol=1e-9)
        # accepting a solution: clip into the box, the slack, the lock band
        x = rng.normal(size=n)
        q_ref, a_unit = _accept(ws, x, start, end)
        lo, hi = np.zeros(end - start), np.zeros(end - start)
        q, s = nat.accept(x, ws.bl, ws.bu, ws.A_unit[sl], ws.norm[sl], beta, ws.band[sl],
                          lo, hi)
        np.testing.assert_array_equal(q, q_ref)
        np.testing.assert_allclose(s, a_unit * ws.norm[sl] - beta, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(lo, a_unit - ws.band[sl], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(hi, a_unit + ws.band[sl], rtol=1e-12, atol=1e-12)
        q2, _ = nat.accept(x, ws.bl, ws.bu, ws.A_unit[sl], ws.norm[sl], beta, ws.band[sl],
                           None, None)  # the last level: no lock
        np.testing.assert_array_equal(q2, q)
        # a satisfied level is locked at its own bounds; a violated one is left alone
        for qdot in (q, np.zeros(n), np.full(n, np.nan)):
            ref = ws.lo_rows.copy(), ws.hi_rows.copy()
            done_ref = _lock_if_satisfied(ws, qdot, start, end)
            want = ws.lo_rows[sl].copy(), ws.hi_rows[sl].copy()
            ws.lo_rows[:], ws.hi_rows[:] = ref
            done = nat.lock_if_satisfied(A_i, qdot, ws.orig_lo[sl], ws.orig_hi[sl],
                                         ws.norm[sl], ws.band[sl], ws.lo_rows[sl],
                                         ws.hi_rows[sl])
            assert done == done_ref
            np.testing.assert_allclose(ws.lo_rows[sl], want[0], rtol=1e-13)
            np.testing.assert_allclose(ws.hi_rows[sl], want[1], rtol=1e-13)


def test_slack_level_setup_and_accept_match_numpy():
    rng = np.random.default_rng(11)
    for _ in range(300):
        n, _, R, ws = random_workspace(rng)
        ws.bl[:] = -rng.uniform(0.01, 1, n + R)
        ws.bu[:] = rng.uniform(0.01, 1, n + R)
        start = int(rng.integers(0, R))
        end = start + int(rng.integers(1, R - start + 1))
        m, sl = end - start, slice(start, end)
        ws.orig_hi[sl][rng.random(m) < 0.3] = ws.orig_lo[sl][rng.random(m) < 0.3] = 0.25
        # the slack QP's rows and bounds (numpy: as in DaqpCascade._solve_slack_level)
        C_ref, bl_ref, bu_ref = _slack_model_arrays(ws, start, end)
        C, bu, bl, _, _ = ws.slack_level(0, start, end, 0.01)
        nat.slack_setup(ws.A_unit, ws.A, start, end, ws.bl, ws.bu, ws.orig_lo, ws.orig_hi,
                        C, bl, bu)
        np.testing.assert_array_equal(C, C_ref)
        np.testing.assert_array_equal(bl, bl_ref)
        np.testing.assert_array_equal(bu, bu_ref)
        # accepting its solution: clip, slack, the lock [lower + s, upper + s] around A qdot
        w = rng.normal(size=n + m)
        q_ref, a_unit = _accept(ws, w[:n], start, end)
        a = a_unit * ws.norm[sl]
        eq = ws.orig_lo[sl] == ws.orig_hi[sl]
        lo = np.where(eq, a, np.minimum(ws.orig_lo[sl] + w[n:], a)) / ws.norm[sl] - ws.band[sl]
        hi = np.where(eq, a, np.maximum(ws.orig_hi[sl] + w[n:], a)) / ws.norm[sl] + ws.band[sl]
        q, s = nat.accept_slack(w, ws.bl, ws.bu, ws.A_unit[sl], ws.norm[sl], ws.orig_lo[sl],
                                ws.orig_hi[sl], ws.band[sl], ws.lo_rows[sl], ws.hi_rows[sl])
        np.testing.assert_array_equal(q, q_ref)
        np.testing.assert_array_equal(s, w[n:])
        np.testing.assert_allclose(ws.lo_rows[sl], lo, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(ws.hi_rows[sl], hi, rtol=1e-12, atol=1e-15)


def _slack_model_arrays(ws, start, end):
    n, m = ws.n, end - start
    C = np.zeros((end, n + m))
    C[start:, n:] = -np.eye(m)
    C[:start, :n] = ws.A_unit[:start]
    C[start:, :n] = ws.A[start:end]
    bl = np.concatenate([ws.bl[:n], np.full(m, -np.inf), ws.lo_rows[:start],
                         ws.orig_lo[start:end]])
    bu = np.concatenate([ws.bu[:n], np.full(m, np.inf), ws.hi_rows[:start],
                         ws.orig_hi[start:end]])
    return C, bl, bu


@pytest.mark.parametrize('stiff', [False, True])
def test_torque_limit_level_matches_numpy(monkeypatch, stiff):
    from ifc_spg.limits.torque_limits import TorqueLimitLevel
    rng = np.random.default_rng(13)
    K = rng.uniform(50, 1000, 7)
    if stiff:
        K[[1, 5]] = 0.0  # position-controlled joints: no torque limit
    tau_max = rng.uniform(20, 200, 7)
    fast, slow = _both(monkeypatch, lambda: TorqueLimitLevel(K, tau_max, 0.002, 0.01, 1e-9))
    assert fast._native is not None and slow._native is None
    for i in range(3000):
        q = rng.normal(size=7)
        q_v = q + rng.normal(scale=rng.choice([1e-3, 0.1, 1.0]), size=7)
        qdot = rng.normal(size=7)
        if i % 100 == 0:
            q[int(rng.integers(7))] = 1e305  # absurd: the level leaves that joint alone
        box = VelocityBox(-rng.uniform(0, 2, 7), rng.uniform(0, 2, 7))
        with np.errstate(all='ignore'):
            want = slow.apply(q, qdot, q_v, box)
        got = fast.apply(q, qdot, q_v, box)
        for name, a, b in (('lower', got[0].lower, want[0].lower),
                           ('upper', got[0].upper, want[0].upper), ('slack', got[1], want[1]),
                           ('box.lower', got[2].lower, want[2].lower),
                           ('box.upper', got[2].upper, want[2].upper)):
            np.testing.assert_allclose(a, b, rtol=1e-14, atol=1e-300, err_msg=name)
        np.testing.assert_array_equal(got[0].A, want[0].A)


def _both(monkeypatch, make):
    """``make()`` with the kernels and with the numpy code."""
    monkeypatch.setattr(native, 'module', nat)
    fast = make()
    monkeypatch.setattr(native, 'module', None)
    slow = make()
    monkeypatch.undo()
    return fast, slow


def test_joint_limit_box_matches_numpy(monkeypatch):
    robot = RobotModel.from_config('lbr_iiwa14')
    fast, slow = _both(monkeypatch, lambda: JointVelocityLimits(
        robot.q_min, robot.q_max, robot.v_max, robot.a_max, 0.002))
    assert fast._native is not None and slow._native is None
    rng = np.random.default_rng(2)
    span = robot.q_max - robot.q_min
    for _ in range(3000):
        # anywhere, near a limit (within the braking distance) or beyond it
        u = rng.choice([rng.uniform(0, 1, 7), rng.uniform(-0.01, 0.03, 7),
                        rng.uniform(0.97, 1.01, 7)])
        q_v = robot.q_min + u * span
        a, b = fast.box(q_v), slow.box(q_v)
        np.testing.assert_allclose(a.lower, b.lower, rtol=1e-14, atol=0)
        np.testing.assert_allclose(a.upper, b.upper, rtol=1e-14, atol=0)


def test_velocity_box_and_integration_match_numpy():
    from ifc_spg.limits import intersect_soft
    rng = np.random.default_rng(3)
    for _ in range(3000):
        n = 7
        lim = VelocityBox(-rng.uniform(0, 2, n), rng.uniform(0, 2, n))
        pb = VelocityBox(-rng.uniform(0, 2, n), rng.uniform(0, 2, n))
        pb.lower[rng.random(n) < 0.1] = np.nan  # an overflowed passivity bound
        pb.upper[rng.random(n) < 0.1] = -np.inf
        pb.upper[rng.random(n) < 0.1] = np.inf
        qd = rng.normal(scale=2, size=n)  # often outside the box: no intersection
        acc = rng.uniform(0, 0.1, n)
        lower, upper = np.maximum(lim.lower, pb.lower), np.minimum(lim.upper, pb.upper)
        lower[np.isnan(lower)] = 0.0
        upper[np.isnan(upper)] = 0.0
        want = intersect_soft(VelocityBox(lower, upper), VelocityBox(qd - acc, qd + acc))
        got = nat.velocity_box(lim.lower, lim.upper, pb.lower, pb.upper, qd, acc)
        np.testing.assert_array_equal(got[0], want.lower)
        np.testing.assert_array_equal(got[1], want.upper)
        want = intersect_soft(lim, VelocityBox(qd - acc, qd + acc))  # without PSPM
        got = nat.velocity_box(lim.lower, lim.upper, None, None, qd, acc)
        np.testing.assert_array_equal(got[0], want.lower)
        np.testing.assert_array_equal(got[1], want.upper)
        q_v, q_min = rng.normal(size=n), -rng.uniform(0, 2, n)
        q_max = rng.uniform(0, 2, n)
        np.testing.assert_array_equal(nat.integrate(q_v, 0.002, qd, q_min, q_max),
                                      np.minimum(np.maximum(q_v + 0.002 * qd, q_min), q_max))


@pytest.mark.filterwarnings('ignore:overflow:RuntimeWarning')  # numpy on the absurd step
@pytest.mark.parametrize('shuffle', [0.0, 1e-4])
def test_energy_tanks_match_numpy(monkeypatch, shuffle):
    rng = np.random.default_rng(7)
    K, D = rng.uniform(20, 400, 7), rng.uniform(0.5, 5, 7)
    modulated = np.array([1, 1, 0, 1, 1, 1, 0], bool)  # two stiff joints
    cfg = PspmConfig(initial_energy=0.05, max_energy=0.1, shuffle=shuffle,
                     shuffle_budget=10 * shuffle)
    fast, slow = _both(monkeypatch, lambda: EnergyTanks(K, D, modulated, 0.002, cfg))
    assert fast._native is not None and slow._native is None
    q = rng.normal(size=7)
    fast.reset(q)
    slow.reset(q)
    for i in range(2000):
        q_new = q + rng.normal(scale=1e-3, size=7)
        if i == 1500:
            q_new[3] = 1e200  # absurd measurement: the tank overflows and empties
        q_v = q_new + rng.normal(scale=0.05, size=7)
        a, b = fast.bounds(q_new, q_v), slow.bounds(q_new, q_v)
        np.testing.assert_allclose(a.lower, b.lower, rtol=1e-12)
        np.testing.assert_allclose(a.upper, b.upper, rtol=1e-12)
        np.testing.assert_allclose(fast.dissipated_min, slow.dissipated_min, rtol=1e-12)
        lo, hi = np.nan_to_num(b.lower, nan=0.0), np.nan_to_num(b.upper, nan=0.0)
        step = np.clip(rng.uniform(-1, 1, 7), lo, hi)
        da, db = fast.update(q_new, q_v, step), slow.update(q_new, q_v, step)
        np.testing.assert_allclose(da, db, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(fast.energy, slow.energy, rtol=1e-12, atol=1e-15)
        np.testing.assert_array_equal(fast.shuffled, slow.shuffled)
        assert fast.deficit == pytest.approx(slow.deficit, abs=1e-15)
        q = q_new if i != 1500 else q
    assert np.all(fast.energy >= 0)


@pytest.mark.parametrize('config,make', [('lbr_iiwa14', lbr_stack),
                                         ('icub_upper_body', icub_stack)])
def test_closed_loop_with_kernels_matches_numpy(monkeypatch, config, make):
    """The whole tick (Table 4.1 on the LBR, Table 3.7 on the iCub) with and without the
    kernels, each in its own closed loop: the same q_v to round-off."""
    robot = RobotModel.from_config(config)
    fast, slow = _both(monkeypatch, lambda: SetPointGenerator(robot, make(robot)))
    assert fast._native is not None and fast._solver._native is not None
    assert slow._native is None and slow._solver._native is None
    loops = [(s, JointImpedancePlant(robot, robot.q_home, substeps=1)) for s in (fast, slow)]
    state = [(p.q, p.qdot, 0.0) for _, p in loops]
    worst = 0.0
    for _ in range(600):
        out = []
        for k, (spg, plant) in enumerate(loops):
            q_v = spg.step(*state[k])
            assert spg.info.status == 'ok'
            out.append(q_v)
            state[k] = plant.step(q_v)
        worst = max(worst, np.abs(out[0] - out[1]).max())
    print(f'{config}: largest |q_v(C) - q_v(numpy)| over 600 ticks: {worst:.1e} rad')
    assert worst < 1e-9


def test_bad_arguments_raise_instead_of_crashing():
    v = np.zeros(7)
    with pytest.raises(ValueError, match='q_prev'):
        nat.pspm_bounds(v, v, np.zeros(6), v, None, v, v, 500.0, v)
    with pytest.raises(TypeError, match='numpy array'):
        nat.integrate([0.0] * 7, 0.002, v, v, v)
    with pytest.raises(ValueError, match='H'):
        nat.normal_form(np.zeros((2, 7)), np.zeros(2), 0.01, np.zeros((6, 6)), v)
    ws = _Workspace(7, 3, 0.01, {})
    bad = [Level('x', np.zeros((2, 6)), np.zeros(2), np.zeros(2), True)]
    with pytest.raises(ValueError, match='level 0'):
        nat.stack_rows(bad, ws.A, ws.orig_lo, ws.orig_hi, ws.norm, ws.A_unit, ws.band, 1e-9)
    with pytest.raises(ValueError, match='rows'):
        nat.stack_rows([Level('x', np.zeros((2, 7)), np.zeros(2), np.zeros(2), True)],
                       ws.A, ws.orig_lo, ws.orig_hi, ws.norm, ws.A_unit, ws.band, 1e-9)
    ro = np.zeros(7)
    ro.setflags(write=False)
    with pytest.raises(ValueError, match='writable'):
        nat.pspm_bounds(v, v, ro, v, None, v, v, 500.0, v)

