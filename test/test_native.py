"""The C kernels of the 2 ms path (ifc_spg.kernels._native) against their numpy reference
(ifc_spg.kernels.reference, used where the module is not built).

Every kernel is compared with the reference on seeded random inputs, including NaN / inf
bounds, stiff joints and boxes that do not intersect; then whole closed-loop runs with the
one and the other, side by side in one process.
"""

import inspect
import os
import re
from types import SimpleNamespace

import numpy as np
from plants import JointImpedancePlant
import pytest

from benchmarks.bench import icub_stack, lbr_stack
from ifc_spg import RobotModel, kernels
from ifc_spg.kernels import reference as ref
from ifc_spg.limits import JointVelocityLimits, VelocityBox
from ifc_spg.pspm import EnergyTanks, PspmConfig
from ifc_spg.spg import SetPointGenerator
from ifc_spg.tasks import Level

nat = kernels.native  # the C module, whatever IFC_SPG_NATIVE selects (None: not built)

def test_native_kernels_are_built():
    """The install builds the kernels (./run setup); IFC_SPG_NATIVE=0 opts out explicitly."""
    assert nat is not None, kernels.describe()
    if os.environ.get('IFC_SPG_NATIVE', '1').strip() == '0':
        assert kernels.active is ref and 'IFC_SPG_NATIVE=0' in kernels.describe()
    else:
        assert kernels.active is nat, kernels.describe()


def test_reference_has_the_kernels_functions_and_signatures():
    """Each C function's docstring starts with its signature: the reference has the same
    functions with the same parameter names, in the same order."""
    c_names = sorted(k for k, v in vars(nat).items() if callable(v) and not k.startswith('_'))
    assert c_names == sorted(ref.__all__)
    for name in c_names:
        first = getattr(nat, name).__doc__.split('\n')[0]
        c_params = re.match(rf'{name}\((.*?)\)', first).group(1).split(', ')
        assert list(inspect.signature(getattr(ref, name)).parameters) == c_params, name


def workspace(n, R):
    """The arrays of a cascade over R rows and n joints, as DaqpCascade keeps them."""
    bl, bu = np.full(n + R, -np.inf), np.full(n + R, np.inf)
    return SimpleNamespace(n=n, A=np.zeros((R, n)), A_unit=np.zeros((R, n)), norm=np.zeros(R),
                           band=np.zeros(R), orig_lo=np.zeros(R), orig_hi=np.zeros(R), bl=bl,
                           bu=bu, lo_rows=bl[n:], hi_rows=bu[n:])


def stack(kern, levels, ws):
    kern.stack_rows(levels, ws.A, ws.orig_lo, ws.orig_hi, ws.norm, ws.A_unit, ws.band, 1e-9)


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
        a, b = workspace(n, R), workspace(n, R)
        stack(ref, levels, a)
        stack(nat, levels, b)
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
    ws = workspace(n, R)
    stack(ref, levels, ws)
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
        H_ref, f_ref = np.zeros((n, n)), np.zeros(n)
        ref.normal_form(A_i, target, 0.01, H_ref, f_ref)
        np.testing.assert_allclose(H, H_ref, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(f, f_ref, rtol=1e-12, atol=1e-9)
        # accepting a solution: clip into the box, the slack, the lock band
        x = rng.normal(size=n)
        args = (x, ws.bl, ws.bu, ws.A_unit[sl], ws.norm[sl], beta, ws.band[sl])
        lo_ref, hi_ref = np.zeros(end - start), np.zeros(end - start)
        q_ref, s_ref = ref.accept(*args, lo_ref, hi_ref)
        np.testing.assert_array_equal(q_ref, np.clip(x, ws.bl[:n], ws.bu[:n]))
        lo, hi = np.zeros(end - start), np.zeros(end - start)
        q, s = nat.accept(*args, lo, hi)
        np.testing.assert_array_equal(q, q_ref)
        np.testing.assert_allclose(s, s_ref, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(lo, lo_ref, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(hi, hi_ref, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(hi - lo, 2 * ws.band[sl], rtol=1e-9, atol=1e-12)
        for kern in (nat, ref):
            q2, _ = kern.accept(*args, None, None)  # the last level: no lock
            np.testing.assert_array_equal(q2, q)
        # a satisfied level is locked at its own bounds; a violated one is left alone
        for qdot in (q, np.zeros(n), np.full(n, np.nan)):
            locks = []
            for kern in (ref, nat):
                lo, hi = np.full(end - start, 7.0), np.full(end - start, 7.0)
                done = kern.lock_if_satisfied(A_i, qdot, ws.orig_lo[sl], ws.orig_hi[sl],
                                              ws.norm[sl], ws.band[sl], lo, hi)
                locks.append((done, lo, hi))
            (done_ref, lo_ref, hi_ref), (done, lo, hi) = locks
            assert done == done_ref
            if not done:
                assert np.all(lo == 7.0) and np.all(hi == 7.0)
            np.testing.assert_allclose(lo, lo_ref, rtol=1e-13)
            np.testing.assert_allclose(hi, hi_ref, rtol=1e-13)
        a = A_i @ np.zeros(n)
        assert ref.lock_if_satisfied(A_i, np.zeros(n), ws.orig_lo[sl], ws.orig_hi[sl],
                                     ws.norm[sl], ws.band[sl], lo, hi) == bool(
            np.all((ws.orig_lo[sl] <= a) & (a <= ws.orig_hi[sl])))


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
        # the slack QP's rows and bounds
        C_want, bl_want, bu_want = _slack_model_arrays(ws, start, end)
        for kern in (ref, nat):
            C, bl, bu = _slack_model_arrays(workspace(n, R), start, end)  # slack columns set
            kern.slack_setup(ws.A_unit, ws.A, start, end, ws.bl, ws.bu, ws.orig_lo,
                             ws.orig_hi, C, bl, bu)
            np.testing.assert_array_equal(C, C_want)
            np.testing.assert_array_equal(bl, bl_want)
            np.testing.assert_array_equal(bu, bu_want)
        # accepting its solution: clip, slack, the lock [lower + s, upper + s] around A qdot
        w = rng.normal(size=n + m)
        q_want = np.clip(w[:n], ws.bl[:n], ws.bu[:n])
        a = (ws.A_unit[sl] @ q_want) * ws.norm[sl]
        eq = ws.orig_lo[sl] == ws.orig_hi[sl]
        lo = np.where(eq, a, np.minimum(ws.orig_lo[sl] + w[n:], a)) / ws.norm[sl] - ws.band[sl]
        hi = np.where(eq, a, np.maximum(ws.orig_hi[sl] + w[n:], a)) / ws.norm[sl] + ws.band[sl]
        for kern in (ref, nat):
            lock_lo, lock_hi = np.zeros(m), np.zeros(m)
            q, s = kern.accept_slack(w, ws.bl, ws.bu, ws.A_unit[sl], ws.norm[sl],
                                     ws.orig_lo[sl], ws.orig_hi[sl], ws.band[sl], lock_lo,
                                     lock_hi)
            np.testing.assert_array_equal(q, q_want)
            np.testing.assert_array_equal(s, w[n:])
            np.testing.assert_allclose(lock_lo, lo, rtol=1e-12, atol=1e-15)
            np.testing.assert_allclose(lock_hi, hi, rtol=1e-12, atol=1e-15)


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
def test_torque_limit_level_matches_numpy(stiff):
    from ifc_spg.limits.torque_limits import TorqueLimitLevel
    rng = np.random.default_rng(13)
    K = rng.uniform(50, 1000, 7)
    if stiff:
        K[[1, 5]] = 0.0  # position-controlled joints: no torque limit
    tau_max = rng.uniform(20, 200, 7)
    fast, slow = _both(lambda kern: TorqueLimitLevel(K, tau_max, 0.002, 0.01, 1e-9,
                                                     kernels=kern))
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


def _both(make):
    """``make(kernels)`` with the C kernels and with the reference."""
    return make(nat), make(ref)


def test_joint_limit_box_matches_numpy():
    robot = RobotModel.from_config('lbr_iiwa14')
    fast, slow = _both(lambda kern: JointVelocityLimits(
        robot.q_min, robot.q_max, robot.v_max, robot.a_max, 0.002, kernels=kern))
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


@pytest.mark.filterwarnings('ignore:invalid value:RuntimeWarning')  # NaN @ 0 in numpy
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
        want_free = intersect_soft(lim, VelocityBox(qd - acc, qd + acc))  # without PSPM
        q_v, q_min = rng.normal(size=n), -rng.uniform(0, 2, n)
        q_max = rng.uniform(0, 2, n)
        for kern in (nat, ref):
            got = kern.velocity_box(lim.lower, lim.upper, pb.lower, pb.upper, qd, acc)
            np.testing.assert_array_equal(got[0], want.lower)
            np.testing.assert_array_equal(got[1], want.upper)
            got = kern.velocity_box(lim.lower, lim.upper, None, None, qd, acc)
            np.testing.assert_array_equal(got[0], want_free.lower)
            np.testing.assert_array_equal(got[1], want_free.upper)
            np.testing.assert_array_equal(kern.integrate(q_v, 0.002, qd, q_min, q_max),
                                          np.minimum(np.maximum(q_v + 0.002 * qd, q_min),
                                                     q_max))


@pytest.mark.filterwarnings('ignore:overflow:RuntimeWarning')  # numpy on the absurd step
@pytest.mark.parametrize('shuffle', [0.0, 1e-4])
def test_energy_tanks_match_numpy(shuffle):
    rng = np.random.default_rng(7)
    K, D = rng.uniform(20, 400, 7), rng.uniform(0.5, 5, 7)
    modulated = np.array([1, 1, 0, 1, 1, 1, 0], bool)  # two stiff joints
    cfg = PspmConfig(initial_energy=0.05, max_energy=0.1, shuffle=shuffle,
                     shuffle_budget=10 * shuffle)
    fast, slow = _both(lambda kern: EnergyTanks(K, D, modulated, 0.002, cfg, kernels=kern))
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
def test_closed_loop_with_kernels_matches_numpy(config, make):
    """The whole tick (Table 4.1 on the LBR, Table 3.7 on the iCub) with and without the
    kernels, each in its own closed loop: the same q_v to round-off."""
    robot = RobotModel.from_config(config)
    fast, slow = _both(lambda kern: SetPointGenerator(robot, make(robot), kernels=kern))
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


def test_collision_rows_match_numpy():
    """Witness points and distance Jacobian rows of a few pairs out of m (normals from the
    witness points, or coal's where touching), C against the reference, on random inputs."""
    rng = np.random.default_rng(8)
    for m, n in ((1, 7), (47, 7), (218, 14)):
        J = np.asfortranarray(rng.normal(size=(6, n)))  # pinocchio's data.J is column-major
        within = np.sort(rng.choice(m, size=max(1, m // 3), replace=False))
        found = list(rng.normal(size=(2 * within.size, 3)))
        a, b = np.array(found[0::2]), np.array(found[1::2])
        dist = np.full(m, 0.5)
        dist[within] = np.linalg.norm(b - a, axis=1)
        dist[rng.random(m) < 0.2] = rng.choice([0.0, -1e-3, 1e-7])  # touching: coal's normal
        mask_a = (rng.random((m, n)) < 0.5).astype(float)
        mask_b = (rng.random((m, n)) < 0.5).astype(float)
        normal0 = rng.normal(size=(m, 3))
        out = []
        for kern in (ref, nat):
            normal, rows = normal0.copy(), np.full((m, n), 7.0)
            pa, pb = np.full((m, 3), np.nan), np.full((m, 3), np.nan)
            kern.collision_rows(J, within.tolist(), found, pa, pb, dist, normal, mask_a, mask_b,
                                1e-6, rows)
            out.append((normal, rows, pa, pb))
        for k in (0, 2, 3):
            np.testing.assert_array_equal(out[1][k], out[0][k])
        np.testing.assert_array_equal(out[1][2][within], a)
        np.testing.assert_allclose(out[1][1], out[0][1], rtol=0, atol=1e-12)
        untouched = np.setdiff1d(np.arange(m), within)
        assert (out[1][1][untouched] == 7.0).all() and np.isnan(out[1][3][untouched]).all()
        for kern in (ref, nat):
            with pytest.raises(ValueError):
                kern.collision_rows(J, within, found[1:], pa, pb, dist, normal0.copy(), mask_a,
                                    mask_b, 1e-6, np.zeros((m, n)))
        with pytest.raises(IndexError):
            nat.collision_rows(J, np.array([m]), found[:2], pa, pb, dist, normal0.copy(), mask_a,
                               mask_b, 1e-6, np.zeros((m, n)))


def test_collision_cull_matches_numpy():
    """The cull across calls (last bounds minus the lever times the joints' motion), C against
    the reference: the same bounds and the same pairs left for coal."""
    rng = np.random.default_rng(9)
    for m, n in ((1, 7), (47, 7), (218, 14)):
        lever = (rng.random((m, n)) < 0.5) * 2.5
        last = rng.normal(size=n)
        q = last + rng.normal(scale=0.02, size=n)
        last_bound = rng.uniform(-0.1, 1.0, m)
        out = []
        for kern in (ref, nat):
            dist = np.full(m, np.nan)
            near = kern.collision_cull(last_bound, lever, q, last, 0.1, dist)
            out.append((dist, near))
        np.testing.assert_allclose(out[1][0], out[0][0], rtol=0, atol=1e-12)
        np.testing.assert_array_equal(out[1][1], out[0][1])
        assert out[1][1].dtype == np.intp
        assert m == 1 or 0 < out[1][1].size < m


def test_collision_level_matches_numpy():
    """The damper level from the rows (the pairs within first, then open rows), C against the
    reference, with fewer and with more pairs within than rows."""
    rng = np.random.default_rng(10)
    for m, n, R in ((1, 7, 1), (47, 7, 24), (218, 14, 8)):
        rows, dist = rng.normal(size=(m, n)), rng.uniform(-0.01, 0.2, m)
        pairs = np.sort(rng.choice(m, size=max(1, m // 2), replace=False))
        out = []
        for kern in (ref, nat):
            A, lower = np.full((R, n), np.nan), np.full(R, np.nan)
            within = kern.collision_level(rows, dist, pairs.tolist(), 0.1, 6.25, 0.02, A, lower)
            out.append((A, lower, within))
        for a, b in zip(out[1], out[0]):
            np.testing.assert_array_equal(a, b)
        assert out[1][2].dtype == np.intp


def test_bad_arguments_raise_instead_of_crashing():
    v = np.zeros(7)
    with pytest.raises(ValueError, match='q_prev'):
        nat.pspm_bounds(v, v, np.zeros(6), v, None, v, v, 500.0, v)
    with pytest.raises(TypeError, match='numpy array'):
        nat.integrate([0.0] * 7, 0.002, v, v, v)
    with pytest.raises(ValueError, match='H'):
        nat.normal_form(np.zeros((2, 7)), np.zeros(2), 0.01, np.zeros((6, 6)), v)
    ws = workspace(7, 3)
    bad = [Level('x', np.zeros((2, 6)), np.zeros(2), np.zeros(2), True)]
    with pytest.raises(ValueError, match='level 0'):
        nat.stack_rows(bad, ws.A, ws.orig_lo, ws.orig_hi, ws.norm, ws.A_unit, ws.band, 1e-9)
    with pytest.raises(ValueError, match='rows'):
        nat.stack_rows([Level('x', np.zeros((2, 7)), np.zeros(2), np.zeros(2), True)],
                       ws.A, ws.orig_lo, ws.orig_hi, ws.norm, ws.A_unit, ws.band, 1e-9)
    ro = np.zeros(7)
    ro.setflags(write=False)
    with pytest.raises(ValueError, match='writable'):
        nat.normal_form(np.zeros((2, 7)), np.zeros(2), 0.01, np.zeros((7, 7)), ro)


def test_pspm_bounds_reads_q_prev_only():
    """The caller books q as the next q_prev; the kernel writes nothing it was given."""
    rng = np.random.default_rng(4)
    q, q_v, q_prev, e = (rng.normal(size=7) for _ in range(4))
    args = (q, q_v, q_prev, np.abs(e), None, np.full(7, 2.0), np.full(7, 0.01), 500.0,
            np.ones(7))
    before = [a.copy() if isinstance(a, np.ndarray) else a for a in args]
    for kern in (nat, ref):
        kern.pspm_bounds(*args)
        for a, b in zip(args, before):
            np.testing.assert_array_equal(a, b)



def _task_bounds_as_before(gain, alpha, lo, lo_ff, hi, hi_ff, gamma, kd, zero_gain):
    """Task.level's bound arithmetic before it became a kernel (75c5db1)."""
    equality = hi is None
    ff_lo, ff_hi = lo_ff, (lo_ff if equality else hi_ff)
    if equality:
        hi = lo
    if gamma is not None:
        ff_lo = ff_lo + gamma
        ff_hi = ff_lo if equality else ff_hi + gamma
    if kd is not None:
        ff_lo = ff_lo + kd
        ff_hi = ff_lo if equality else ff_hi + kd
    if zero_gain:
        with np.errstate(invalid='ignore'):
            beta_lo = gain * (lo - alpha) + ff_lo
            beta_hi = gain * (hi - alpha) + ff_hi
        beta_lo[np.isneginf(lo)] = -np.inf
        beta_hi[np.isposinf(hi)] = np.inf
        return beta_lo, beta_hi
    beta_lo = gain * (lo - alpha) + ff_lo
    return beta_lo, (beta_lo if equality else gain * (hi - alpha) + ff_hi)


def test_task_bounds_equal_the_numpy_code_bit_for_bit():
    """The task bound kernel gives the bits of the numpy code it replaced (C and reference),
    unbounded sides, zero gains, gamma and k_d included; an equality's upper is its lower."""
    rng = np.random.default_rng(32)
    for k in range(3000):
        m = int(rng.integers(1, 8))
        gain = rng.uniform(0, 20, m)
        zero_gain = k % 3 == 0
        if zero_gain:
            gain[rng.random(m) < 0.5] = 0.0
        alpha, lo_ff, hi_ff = rng.normal(size=(3, m))
        lo = rng.normal(size=m) - 1.0
        hi = rng.normal(size=m) + 1.0
        lo[rng.random(m) < 0.3] = -np.inf
        hi[rng.random(m) < 0.3] = np.inf
        gamma = rng.normal(size=m) if k % 2 else None
        kd = rng.normal(size=m) if k % 5 == 0 else None
        equality = k % 4 == 1
        if equality:
            lo, hi, hi_ff = rng.normal(size=m), None, None
            if zero_gain:  # Task.level passes an equality's upper side here
                hi, hi_ff = lo, lo_ff
        want = _task_bounds_as_before(gain, alpha, lo, lo_ff, None if equality else hi,
                                      hi_ff, gamma, kd, zero_gain)
        for kern in (nat, ref):
            got = kern.task_bounds(gain, alpha, lo, lo_ff, hi, hi_ff, gamma, kd, zero_gain)
            np.testing.assert_array_equal(got[0], want[0])
            np.testing.assert_array_equal(got[1], want[1])
            if equality and not zero_gain:
                assert got[1] is got[0]


def test_pose_error_matches_pinocchio():
    """The pose task's error and Jacobian in C against pinocchio's log3 and Jlog3 (the
    reference): rotation errors from 1e-9 rad to pi, both of log3's series branches and its
    branch at pi, J in either memory layout, the full pose and the rotation only.

    Away from pi the two agree to round-off. Near pi the log is ill-conditioned (theta / sin
    theta amplifies the round-off of R_e, computed by BLAS in the one and by a loop in the
    other), and at pi exactly its sign is a choice: there both must give an angle of pi
    about the same axis, up to its sign."""
    import pinocchio as pin
    rng = np.random.default_rng(44)
    angles = [1e-9, 1e-6, 5e-5, 1.2e-4, 1.3e-4, 1e-3, 0.1, 1.0, 2.5, np.pi - 0.1,
              np.pi - 1e-2, np.pi - 1e-5, np.pi]
    for k in range(3000):
        angle = angles[k % len(angles)]
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        R_ref = pin.exp3(rng.normal(size=3))
        R = pin.exp3(axis * angle) @ R_ref
        J = rng.normal(size=(6, int(rng.integers(1, 18))))
        if k % 2:
            J = np.asfortranarray(J)  # pinocchio's own Jacobians are column-major
        p, p_ref = rng.normal(size=(2, 3))
        for args in ((p, p_ref, R, R_ref, J), (None, None, R, R_ref, J)):
            (x, Jx), (x_ref, Jx_ref) = nat.pose_error(*args), ref.pose_error(*args)
            rows = 6 if args[0] is not None else 3
            assert x.shape == (rows,) and Jx.shape == (rows, J.shape[1])
            if rows == 6:
                np.testing.assert_array_equal(x[:3], p - p_ref)
                np.testing.assert_array_equal(Jx[:3], J[:3])
            e, e_ref = x[-3:], x_ref[-3:]
            if angle == np.pi:
                assert abs(np.linalg.norm(e) - np.pi) < 1e-9
                assert min(np.abs(e - e_ref).max(), np.abs(e + e_ref).max()) < 1e-9
                continue
            tol = 1e-13 if angle < 3.0 else 1e-9
            np.testing.assert_allclose(e, e_ref, rtol=0, atol=tol)
            np.testing.assert_allclose(Jx, Jx_ref, rtol=0, atol=tol * (1 + np.abs(J).max()))
            np.testing.assert_allclose(np.linalg.norm(e), angle, rtol=1e-9, atol=1e-15)
    with pytest.raises(ValueError, match='3 x 3'):
        nat.pose_error(None, None, np.eye(2), np.eye(3), np.zeros((6, 7)))
    with pytest.raises(ValueError, match='J 6 x n'):
        nat.pose_error(None, None, np.eye(3), np.eye(3), np.zeros((3, 7)))
    with pytest.raises(TypeError, match='both'):
        nat.pose_error(np.zeros(3), None, np.eye(3), np.eye(3), np.zeros((6, 7)))


def test_a_stale_build_without_a_newer_kernel_is_not_used(monkeypatch):
    """A _native.so built from an older _native.c lacks newer kernels: it must not be chosen
    (every tick would fail at the first call and the SPG hold), and describe() says why."""
    import importlib
    import types

    old = types.ModuleType('ifc_spg.kernels._native')
    for name in ref.__all__[1:]:  # every kernel but the first
        setattr(old, name, getattr(ref, name))
    monkeypatch.setattr(importlib, 'import_module', lambda name: old)
    monkeypatch.setattr(kernels, 'stale', [])
    assert kernels._load() is None
    assert kernels.stale == [ref.__all__[0]]
    monkeypatch.setattr(kernels, 'active', ref)
    monkeypatch.setattr(kernels, '_disabled', False)
    assert 'stale build without ' + ref.__all__[0] in kernels.describe()
    monkeypatch.setattr(kernels, 'stale', [])
    setattr(old, ref.__all__[0], getattr(ref, ref.__all__[0]))
    assert kernels._load() is old
