"""First-order constraint estimator (thesis 5.2.2, eqs. 5.4/5.5).

The direction of possible motion d_p is estimated from the end-effector's translational
velocity only (no force data)::

    pdot := pdot            if |pdot| >= v_th
            w0 d_hat        otherwise                                   (5.5)
    d_hat = norm( (1/N) sum_{j<N} pdot[i - j] )                         (5.4)

Normalization after filtering weights fast samples more than slow (noisy) ones. The
window is a ring buffer with a running sum, O(1) per tick (the sum is recomputed from
the buffer once per N samples so round-off cannot accumulate). The buffer starts full of
w0 d_p0, which seeds the initial direction: the estimate stays d_p0 until the end
effector moves faster than v_th.
"""

import numpy as np

from ifc_spg.constrained.params import EstimatorParams
from ifc_spg.errors import ParameterError

__all__ = ['DirectionEstimator', 'FixedDirection', 'angle_between']


def angle_between(a, b):
    """Angle between two 3-vectors in [rad] (0 if either is zero)."""
    na, nb = np.linalg.norm(a), np.linalg.norm(b)
    if na < 1e-12 or nb < 1e-12:
        return 0.0
    # atan2 of |a x b| and a.b is accurate for small and large angles alike.
    c = np.cross(a, b)
    return float(np.arctan2(np.linalg.norm(c), float(np.dot(a, b))))


class DirectionEstimator:
    """SMA direction estimator with dead band.

    Args:
        params: :class:`~ifc_spg.constrained.params.EstimatorParams` (window N, v_th, w0,
            initial direction d_p0); keyword overrides are accepted as well.

    Attributes:
        direction: The current estimate d_hat (3,), unit length, read-only view.
        samples: Number of updates so far.
        last_valid: True when the last sample was outside the dead band.
    """

    def __init__(self, params=None, **overrides):
        if params is None:
            params = EstimatorParams(**overrides)
        elif overrides:
            from dataclasses import replace
            params = replace(params, **overrides)
        if not isinstance(params, EstimatorParams):
            raise ParameterError(f'params must be an EstimatorParams, got {params!r}')
        self.params = params
        self.window = int(params.window)
        self.v_threshold = float(params.v_threshold)
        self.w0 = float(params.w0)
        self._buf = np.zeros((self.window, 3))
        self._sum = np.zeros(3)
        self._dir = np.zeros(3)
        self._stamp = None
        self.reset(params.initial_direction)

    def reset(self, initial_direction=None):
        """Restart from ``initial_direction`` (default: d_p0 of the parameters)."""
        d = np.asarray(self.params.initial_direction if initial_direction is None
                       else initial_direction, dtype=float).reshape(-1)
        norm = np.linalg.norm(d)
        if d.shape != (3,) or not np.isfinite(norm) or norm < 1e-12:
            raise ParameterError(f'initial direction must be 3 finite numbers, not all zero, '
                                 f'got {initial_direction!r}')
        self._dir[:] = d / norm
        self._buf[:] = self.w0 * self._dir
        self._sum[:] = self._buf.sum(axis=0)
        self._k = 0
        self.samples = 0
        self.last_valid = False
        self._stamp = None

    @property
    def direction(self):
        """The current estimate d_hat (unit 3-vector, base frame); a read-only view."""
        v = self._dir.view()
        v.setflags(write=False)
        return v

    @property
    def filtered_velocity(self):
        """The SMA of (5.4) before its normalisation in [m/s] (3,), a new array.

        ``(1/N) sum_{j<N} pdot[i - j]``; dead-band samples (5.5) count as ``w0 d_hat``.
        """
        return self._sum / self.window

    def update(self, pdot, stamp=None):
        """Add one velocity sample and return the new estimate d_hat.

        Args:
            pdot: End-effector translational velocity in [m/s] (3,), base frame.
            stamp: Optional tick identity (e.g. the time stamp): a second call with the same
                stamp does nothing, so several tasks may share one estimator.

        Returns:
            d_hat (read-only view, unit length).
        """
        if stamp is not None:
            if stamp == self._stamp:
                return self.direction
            self._stamp = stamp
        v = np.asarray(pdot, dtype=float)
        speed = float(np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]))
        if speed >= self.v_threshold and np.isfinite(speed):
            sample = v
            self.last_valid = True
        else:
            sample = self.w0 * self._dir
            self.last_valid = False
        k = self._k
        self._sum += sample - self._buf[k]
        self._buf[k] = sample
        k += 1
        if k == self.window:
            k = 0
            self._sum[:] = self._buf.sum(axis=0)
        self._k = k
        self.samples += 1
        s = self._sum
        norm = float(np.sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]))
        if norm > 1e-12 * self.window:
            self._dir[:] = s / norm
        return self.direction

    def projector(self):
        """P_hat = d_hat d_hat^T (3 x 3), a new array."""
        return np.outer(self._dir, self._dir)

    def error_angle(self, true_direction):
        """Estimation error angle between d_hat and the true direction in [rad]."""
        return angle_between(self._dir, true_direction)


class FixedDirection(DirectionEstimator):
    """A constant "estimate" (the thesis' induced d_hat = const of Sec. 5.5.3).

    Same interface as :class:`DirectionEstimator`; :meth:`update` ignores the samples.

    Args:
        direction: The direction (3,), normalized on use.
    """

    def __init__(self, direction):
        super().__init__(EstimatorParams(window=1, initial_direction=tuple(
            np.asarray(direction, dtype=float).reshape(-1))))

    def update(self, pdot, stamp=None):
        """Count the sample; the direction stays fixed. Returns it."""
        self.samples += 1
        return self.direction
