"""Joint limits (docs/SPEC.md §4) and the closed-form torque-limit level (4.3) vs references."""

import numpy as np
import pytest

from ifc_spg import RobotModel
from ifc_spg.cascade import DaqpCascade
from ifc_spg.limits import (
    JointVelocityLimits,
    VelocityBox,
    intersect_soft,
    joint_velocity_bounds,
    stopping_velocity,
)
from ifc_spg.limits.torque_limits import TorqueLimitLevel
from ifc_spg.tasks import Level

IIWA = RobotModel.from_config('lbr_iiwa14')
DT = 0.002


def test_fast_limits_equal_the_function():
    r = IIWA
    fast = JointVelocityLimits(r.q_min, r.q_max, r.v_max, r.a_max, DT)
    rng = np.random.default_rng(0)
    # distances at which v_stop reaches v_max (the fast path's switch), found by a scan
    d_grid = np.linspace(0.0, 3.0, 300001)
    d_free = np.array([d_grid[np.argmax(stopping_velocity(d_grid, a, DT) >= v)]
                       for a, v in zip(r.a_max, r.v_max)])
    for i in range(3000):
        if i % 3 == 0:
            q = rng.uniform(r.q_min, r.q_max)
        elif i % 3 == 1:
            q = np.clip(r.q_max - rng.exponential(0.01, 7), r.q_min, r.q_max)
        else:  # around the switch distance, from either limit
            d = d_free * rng.uniform(0.99, 1.01, 7)
            q = np.where(rng.random(7) < 0.5, r.q_min + d, r.q_max - d)
        a, b = fast.box(q), joint_velocity_bounds(q, r.q_min, r.q_max, r.v_max, r.a_max, DT)
        np.testing.assert_allclose(a.lower, b.lower, atol=1e-12)
        np.testing.assert_allclose(a.upper, b.upper, atol=1e-12)


@pytest.mark.parametrize('a_max', [0.5, 8.7, 100.0])
def test_braking_along_the_stopping_curve_never_needs_more_than_a_max(a_max):
    """v_stop(d - dT v_stop(d)) >= v_stop(d) - a_max dT, and braking stops inside d."""
    c = a_max * DT
    for d in np.concatenate([np.linspace(0, 1e-3, 500), np.linspace(1e-3, 2.0, 500)]):
        v = stopping_velocity(d, a_max, DT)
        assert v <= d / DT + 1e-12
        assert stopping_velocity(d - DT * v, a_max, DT) >= v - c - 1e-12
        # braking from v by a_max dT per tick covers at most d
        pos, vel = 0.0, v
        while vel > 0:
            pos += DT * vel
            vel -= c
        assert pos <= d * (1 + 1e-12) + 1e-15


def test_closed_form_torque_level_equals_the_cascade():
    """Folding the torque-limit level into the box gives the cascade's solution."""
    rng = np.random.default_rng(3)
    n = 7
    rho = 0.01
    worst = 0.0
    for _ in range(300):
        K = rng.uniform(20, 400, n)
        tau_max = rng.uniform(5, 50, n)
        lim = TorqueLimitLevel(K, tau_max, DT, rho, DaqpCascade.lock_tolerance)
        q = rng.normal(size=n)
        q_v = q + rng.normal(scale=0.3, size=n) * tau_max / K  # sometimes beyond the limit
        qdot = rng.normal(scale=0.5, size=n)
        box = VelocityBox(-rng.uniform(0.01, 2, n), rng.uniform(0.01, 2, n))
        others = []
        for i in range(int(rng.integers(1, 4))):
            m = int(rng.integers(1, 4))
            b = rng.normal(size=m)
            others.append(Level(f'L{i}', rng.normal(size=(m, n)), b, b, True))
        level, slack, folded = lim.apply(q, qdot, q_v, box)
        fast = DaqpCascade(n, rho).solve(others, folded)
        ref = DaqpCascade(n, rho).solve([level] + others, box)
        assert fast.status == ref.status == 'ok'
        np.testing.assert_allclose(slack, ref.slacks[0], atol=1e-6)
        err = np.abs(fast.qdot_v - ref.qdot_v).max()
        worst = max(worst, err)
        assert err < 1e-6
    print(f'closed-form torque level vs cascade: max |dqdot| {worst:.1e}')


def _intersect_soft_reference(hard, soft):
    """The definition, case by case: intersection, or the nearest end of the hard box."""
    lower, upper = [], []
    for hl, hu, sl, su in zip(hard.lower, hard.upper, soft.lower, soft.upper):
        if su < hl:  # soft box entirely below the hard box
            lower.append(hl), upper.append(hl)
        elif sl > hu:  # entirely above
            lower.append(hu), upper.append(hu)
        else:
            lower.append(max(hl, sl)), upper.append(min(hu, su))
    return np.array(lower), np.array(upper)


def test_intersect_soft_matches_its_definition():
    rng = np.random.default_rng(7)
    for _ in range(300):
        n = 7
        hl = rng.uniform(-2, 1, n)
        hard = VelocityBox(hl, hl + rng.uniform(0, 1, n) * (rng.random(n) > 0.1))
        sl = rng.uniform(-3, 2, n)
        soft = VelocityBox(sl, sl + rng.uniform(0, 1, n))
        got = intersect_soft(hard, soft)
        ref = _intersect_soft_reference(hard, soft)
        np.testing.assert_array_equal(got.lower, ref[0])
        np.testing.assert_array_equal(got.upper, ref[1])
        assert np.all(got.lower <= got.upper)
        assert np.all(got.lower >= hard.lower) and np.all(got.upper <= hard.upper)
