"""Tests of the first-order constraint estimator (5.4/5.5), the parameters and the metrics."""

import math

import numpy as np
import pytest

from ifc_spg.constrained import (
    DirectionEstimator,
    EstimatorParams,
    StrategyParams,
    load_params,
    params_from_dict,
)
from ifc_spg.constrained.metrics import (
    error_angles,
    perpendicular_force,
    summarize,
    time_to_open,
)
from ifc_spg.errors import ParameterError

DT = 0.002


def _slow_reference(samples, n, v_th, w0, d0):
    """Obvious O(N) implementation of (5.4)/(5.5): keep the list, average the last N."""
    d = np.asarray(d0, float) / np.linalg.norm(d0)
    window = [w0 * d] * n
    out = []
    for v in samples:
        window.append(v if np.linalg.norm(v) >= v_th else w0 * d)
        window = window[-n:]
        m = np.mean(window, axis=0)
        if np.linalg.norm(m) > 0:
            d = m / np.linalg.norm(m)
        out.append(d)
    return np.array(out)


def test_ring_buffer_matches_slow_reference():
    rng = np.random.default_rng(3)
    samples = rng.normal(scale=0.02, size=(700, 3)) + [0.0, 0.01, 0.005]
    est = DirectionEstimator(window=37, v_threshold=0.015, w0=0.004,
                             initial_direction=(1.0, 0.0, 0.0))
    got = np.array([np.array(est.update(v)) for v in samples])
    ref = _slow_reference(samples, 37, 0.015, 0.004, (1.0, 0.0, 0.0))
    np.testing.assert_allclose(got, ref, atol=1e-12)


def test_filtered_velocity_is_the_mean_of_the_last_n_samples():
    """(5.4) before its normalisation (Fig. 5.2's z_SMA); dead-band samples count as w0 d."""
    rng = np.random.default_rng(5)
    samples = rng.normal(scale=0.02, size=(300, 3)) + [0.0, 0.0, 0.01]
    est = DirectionEstimator(window=25, v_threshold=0.0, w0=0.004,
                             initial_direction=(0.0, 0.0, 1.0))
    for i, v in enumerate(samples):
        est.update(v)
        window = [np.array([0.0, 0.0, 0.004])] * 25 + list(samples[:i + 1])
        np.testing.assert_allclose(est.filtered_velocity, np.mean(window[-25:], axis=0),
                                   atol=1e-15)


def test_converges_from_45_degrees_on_a_noisy_straight_line():
    rng = np.random.default_rng(0)
    true = np.array([0.0, 0.0, 1.0])
    est = DirectionEstimator(EstimatorParams(initial_direction=(-1.0, 0.0, 1.0)))
    assert math.degrees(est.error_angle(true)) == pytest.approx(45.0)
    for _ in range(2 * 500):
        est.update(0.05 * true + rng.normal(scale=0.01, size=3))
    # Noise of the mean of 500 samples: 0.01 / sqrt(500) / 0.05 rad ~ 0.5 deg.
    assert math.degrees(est.error_angle(true)) < 2.0


def test_circle_arc_error_equals_the_sma_lag():
    """Uniform circular motion: the mean of N velocities points to the middle of the arc,
    so the steady error angle is omega (N - 1) dT / 2 exactly."""
    n, omega, r = 200, 0.5, 0.17
    est = DirectionEstimator(window=n, v_threshold=0.01, initial_direction=(0.0, 1.0, 0.0))
    errs = []
    for k in range(3 * n):
        phi = omega * k * DT
        v = r * omega * np.array([-math.sin(phi), math.cos(phi), 0.0])
        est.update(v)
        errs.append(est.error_angle(v))
    expected = omega * (n - 1) * DT / 2.0
    np.testing.assert_allclose(errs[n:], expected, rtol=1e-6)


def test_dead_band_holds_the_estimate_and_seeds_d0():
    d0 = np.array([1.0, 1.0, 0.0]) / math.sqrt(2)
    est = DirectionEstimator(window=50, v_threshold=0.01, initial_direction=d0)
    rng = np.random.default_rng(1)
    for _ in range(300):  # below the dead band: the seed direction is kept exactly
        v = rng.normal(size=3)
        est.update(0.009 * v / np.linalg.norm(v))
        assert not est.last_valid
    np.testing.assert_allclose(est.direction, d0, atol=1e-12)
    for _ in range(100):  # fast motion along z takes over
        est.update([0.0, 0.0, 0.05])
    hold = np.array(est.direction)
    assert hold[2] > 0.999
    for _ in range(300):  # motion stops: the last valid estimate is held
        est.update([0.003, -0.002, 0.0])
    np.testing.assert_allclose(est.direction, hold, atol=1e-12)


def test_same_stamp_updates_once():
    est = DirectionEstimator(window=2, v_threshold=0.0, initial_direction=(1, 0, 0))
    est.update([0.0, 1.0, 0.0], stamp=0.5)
    d = np.array(est.direction)
    est.update([0.0, 0.0, 1.0], stamp=0.5)
    np.testing.assert_allclose(est.direction, d)
    assert est.samples == 1


def _lag_and_noise(n, rng):
    """Time to follow a 90 deg direction change, and the steady noise (deg) before it."""
    est = DirectionEstimator(window=n, v_threshold=0.01, initial_direction=(1, 0, 0))
    a, b = np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    noise = []
    for k in range(1500):
        est.update(0.05 * a + rng.normal(scale=0.03, size=3))
        if k >= 1000:
            noise.append(math.degrees(est.error_angle(a)))
    for k in range(1500):
        est.update(0.05 * b + rng.normal(scale=0.03, size=3))
        if math.degrees(est.error_angle(b)) < 10.0:
            return k * DT, float(np.sqrt(np.mean(np.square(noise))))
    return math.inf, float(np.sqrt(np.mean(np.square(noise))))


def test_window_trades_lag_for_noise():
    """Fig. 5.2/5.5: a longer window is smoother but lags more."""
    lag_s, noise_s = _lag_and_noise(100, np.random.default_rng(5))
    lag_l, noise_l = _lag_and_noise(500, np.random.default_rng(5))
    assert lag_l > 3.0 * lag_s
    assert noise_l < 0.6 * noise_s
    # SMA noise scales with 1/sqrt(N): about sqrt(5) between the two windows.
    assert noise_s / noise_l == pytest.approx(math.sqrt(5.0), rel=0.35)


def test_params_defaults_match_the_thesis_and_the_yaml():
    p = StrategyParams()
    assert (p.dt, p.stiffness, p.kappa, p.nu) == (0.002, 40.0, 9.0, 0.05)
    assert (p.estimator.window, p.estimator.v_threshold) == (500, 0.01)
    assert load_params('config/constrained_manipulation.yaml') == p


@pytest.mark.parametrize('bad, match', [
    ({'kapa': 3}, "unknown key 'kapa'; did you mean 'kappa'"),
    ({'estimator': {'windw': 3}}, "unknown key 'windw'; did you mean 'window'"),
    ({'orientation': 'align'}, 'choose one of free, fixed, align_z, release_y'),
    ({'estimator': {'window': 0}}, 'window'),
])
def test_params_errors_name_the_key(bad, match):
    with pytest.raises(ParameterError, match=match):
        params_from_dict(bad)


def test_metrics_against_hand_computation():
    f = np.array([[3.0, 4.0, 0.0], [0.0, 0.0, 2.0], [1.0, 1.0, 1.0]])
    d = np.array([1.0, 0.0, 0.0])
    np.testing.assert_allclose(perpendicular_force(f, d), [4.0, 2.0, math.sqrt(2)])
    np.testing.assert_allclose(np.degrees(error_angles([[1, 1, 0]], [[1, 0, 0]])), [45.0])
    t = np.arange(5) * 0.5
    q = np.array([0.0, 0.1, 0.2, 0.3, 0.4])
    assert time_to_open(t, q, 0.25) == 1.5
    assert time_to_open(t, q, 0.5) is None
    m = summarize(t, q, np.tile([0.0, 3.0, 4.0], (5, 1)), [0.0, 0.0, 1.0], target=0.25,
                  force_limit=4.5)
    assert m['rms_f_perp'] == pytest.approx(3.0)
    assert m['success'] is False  # |f| = 5 N > 4.5 N
    assert m['travel'] == pytest.approx(0.4)


def test_pooled_rms_is_the_rms_of_the_concatenated_runs():
    """The thesis' "overall RMS" over several runs (5.5.3): from per-run summaries."""
    from ifc_spg.constrained.metrics import pooled_rms
    rng = np.random.default_rng(7)
    runs, series = [], []
    for n in (40, 7, 123):
        t = np.arange(n) * 0.002
        f = rng.normal(size=(n, 3))
        runs.append(summarize(t, np.zeros(n), f, [0.0, 0.0, 1.0], static_force=2.0 * f))
        series.append(perpendicular_force(f, [0.0, 0.0, 1.0]))
        assert runs[-1]['samples'] == n
    slow = math.sqrt(np.mean(np.concatenate(series) ** 2))
    assert pooled_rms(runs) == pytest.approx(slow, rel=1e-12)
    assert pooled_rms(runs, 'rms_fs_perp') == pytest.approx(2.0 * slow, rel=1e-12)
    # Not the mean of the per-run RMS values (the runs have different lengths).
    assert abs(pooled_rms(runs) - np.mean([r['rms_f_perp'] for r in runs])) > 1e-3
    assert pooled_rms([]) == 0.0
