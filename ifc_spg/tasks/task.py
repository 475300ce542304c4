"""Task base class: a task is a value, a Jacobian and a velocity compensation (docs/SPEC.md §2).

Every task maps the virtual configuration to a value alpha in its subspace (m
coordinates), with A = d(alpha)/d(q_v) and gamma, the rate of alpha caused by the measured
joint velocity (Table 3.1). Bounds alpha_m <= alpha <= alpha_M become velocity bounds
(4.25-4.28)::

    beta_m = Lambda (alpha_m - alpha) + ff_m + gamma
    beta_M = Lambda (alpha_M - alpha) + ff_M + gamma

and the cascade asks for beta_m <= A qdot_v <= beta_M. Equal bounds make an equality task.
"""

from __future__ import annotations

import abc
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from ifc_spg.errors import IfcSpgError
from ifc_spg.tasks.bounds import INIT, Bound, as_bound

if TYPE_CHECKING:  # annotations only: the model and kinematics do not import tasks
    from ifc_spg.kinematics import Kinematics
    from ifc_spg.model.robot_model import RobotModel

__all__ = ['Level', 'Task']


class Level(NamedTuple):
    """One priority level of the cascade: ``lower <= A qdot_v <= upper``.

    Attributes:
        name: Task name (for reports).
        A: Task Jacobian in subspace coordinates, shape (m, n).
        lower: Lower velocity bound beta_m, shape (m,) (may hold -inf).
        upper: Upper velocity bound beta_M, shape (m,) (may hold +inf).
        equality: True when lower == upper by construction (an equality task).
    """

    name: str
    A: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    equality: bool


class Task(abc.ABC):
    """Base class of the four task archetypes (abstract).

    A subclass implements :meth:`compute_value` and :meth:`compute_jacobian` (and
    :meth:`compute_gamma` where gamma is not zero); it may also override :meth:`compute`
    with a fused computation of the three, which must agree with them. A subclass that
    implements neither value nor Jacobian cannot be instantiated (``TypeError`` names the
    missing methods).

    Args:
        robot: The :class:`~ifc_spg.model.RobotModel`.
        dim: Task dimension m (columns of S).
        name: Task name used in reports and errors.
        equal: Target (equality task): number, list, 'init' or a :class:`Bound`.
        lower: Lower bound (inequality task), default unbounded.
        upper: Upper bound (inequality task), default unbounded.
        gain: Convergence gain Lambda in [1/s] (scalar or per direction), >= 0.
        feedforward: 'trajectory' (the bounds' rates, default), None (zero) or a
            constant rate per direction in task units per second.
        velocity_gain: k_d, adds k_d * (measured task rate) to the feed-forward
            (Table 4.5's deliberately destabilizing regulator uses it).
        compensate_velocity: Add gamma (True, default); False cancels the compensation
            of the measured velocity (Table 5.1).
    """

    kind = 'task'
    has_gamma = True  # False where gamma is identically zero (position tasks)

    def __init__(self, robot: RobotModel, *, dim: int, name: str | None = None,
                 equal: Any = None, lower: Any = None, upper: Any = None, gain: Any = 1.0,
                 feedforward: Any = 'trajectory', velocity_gain: float = 0.0,
                 compensate_velocity: bool = True) -> None:
        self.robot = robot
        self.name = name or self.kind
        self.dim = int(dim)
        if self.dim <= 0:
            raise IfcSpgError(f"task '{self.name}': empty subspace")
        if equal is not None and (lower is not None or upper is not None):
            raise IfcSpgError(f"task '{self.name}': give either 'equal' or 'lower'/'upper', "
                              'not both')
        if equal is None and lower is None and upper is None:
            raise IfcSpgError(f"task '{self.name}': no bounds; give 'equal' (equality task) "
                              "or 'lower'/'upper' (inequality task)")
        self.equality = equal is not None
        if self.equality:
            self._lower = self._upper = as_bound(equal, self.dim, f'{self.name}.equal')
        else:
            inf = np.full(self.dim, np.inf)
            self._lower = as_bound(-inf if lower is None else lower, self.dim,
                                   f'{self.name}.lower')
            self._upper = as_bound(inf if upper is None else upper, self.dim,
                                   f'{self.name}.upper')
        gain = np.broadcast_to(np.asarray(gain, dtype=float), (self.dim,)).copy()
        if not np.all(np.isfinite(gain)) or np.any(gain < 0):
            raise IfcSpgError(f"task '{self.name}': gain must be finite and >= 0, got "
                              f'{gain.tolist()}')
        self.gain = gain
        self._zero_gain = bool(np.any(gain == 0.0))
        if isinstance(feedforward, str):
            if feedforward != 'trajectory':
                raise IfcSpgError(f"task '{self.name}': feedforward must be 'trajectory', "
                                  f'none or numbers, got {feedforward!r}')
            self._ff: np.ndarray | None = None
        elif feedforward is None:
            self._ff = np.zeros(self.dim)
        else:
            self._ff = as_bound(feedforward, self.dim, f'{self.name}.feedforward').evaluate(0)[0]
        self.velocity_gain = float(velocity_gain)
        if not np.isfinite(self.velocity_gain):
            raise IfcSpgError(f"task '{self.name}': velocity_gain must be finite")
        self.compensate_velocity = bool(compensate_velocity)
        self._active_lower: Bound | None = None
        self._active_upper: Bound | None = None
        # the bounds that take a value at activation (init, or a bound with its own activate)
        self._to_activate = [b is INIT or type(b).activate is not Bound.activate for b in
                             ((self._lower,) if self.equality else (self._lower, self._upper))]

    # -- to implement: compute_value and compute_jacobian ---------------------------------
    @abc.abstractmethod
    def compute_value(self, kin: Kinematics) -> np.ndarray:
        """Task value alpha (m,) at this tick's configuration."""

    @abc.abstractmethod
    def compute_jacobian(self, kin: Kinematics) -> np.ndarray:
        """Task Jacobian A = d(alpha)/d(q_v), shape (m, n)."""

    def compute_gamma(self, kin: Kinematics) -> np.ndarray:
        """Velocity compensation gamma (m,) (Table 3.1); zero for position tasks."""
        return np.zeros(self.dim)

    def compute(self, kin: Kinematics) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return ``(alpha (m,), A (m, n), gamma (m,))`` at this tick's configuration.

        Calls the three ``compute_*`` methods; subclasses may fuse them.
        """
        return self.compute_value(kin), self.compute_jacobian(kin), self.compute_gamma(kin)

    def compute_measured_rate(self, kin: Kinematics) -> np.ndarray:
        """Rate of alpha due to the measured joint velocity (m,)."""
        return -self.compute_gamma(kin)

    # -- activation and levels ------------------------------------------------------------
    @property
    def lower_bound(self) -> Bound:
        """The lower bound as given (``init`` entries unresolved until activation)."""
        return self._lower

    @property
    def upper_bound(self) -> Bound:
        """The upper bound as given (the target itself for an equality task)."""
        return self._upper

    @property
    def active(self) -> bool:
        """True once :meth:`activate` captured the ``init`` values."""
        return self._active_lower is not None

    #: ``compute_value(kin)`` is ``compute(kin)[0]``: a level's first build activates its
    #: bounds with the value it computes anyway (set by the subclasses where it holds)
    _value_is_computed = False

    def activate(self, kin: Kinematics) -> None:
        """Capture ``init`` bounds from the current value; called when the stack starts."""
        self._capture(kin)
        self._activate_bounds(kin, None)

    def _capture(self, kin: Kinematics) -> None:  # noqa: B027 -- a hook, empty by default
        """Capture what the task value depends on at activation (subclasses: references)."""

    def _activate_bounds(self, kin: Kinematics, value: np.ndarray | None) -> None:
        """Activate the bounds at the task value ``value`` (None: ``compute_value(kin)``)."""
        if True not in self._to_activate:  # (the bounds as given)
            self._active_lower, self._active_upper = self._lower, self._upper
            return
        init = None
        bounds: list[Bound] = []
        # an equality's upper bound is its lower one (activated once)
        for b, to_activate in zip((self._lower, self._upper), self._to_activate):
            if to_activate:
                if init is None:  # (a copy: a bound may keep it, the value's buffer not)
                    init = np.array(self.compute_value(kin) if value is None else value,
                                    dtype=float)
                b = b.activate(init)
            bounds.append(b)
        self._active_lower = bounds[0]
        self._active_upper = bounds[-1]

    def _active_bounds(self) -> tuple[Bound, Bound]:
        lower, upper = self._active_lower, self._active_upper
        if lower is None or upper is None:
            raise IfcSpgError(f"task '{self.name}' is not active; call activate(kin) first")
        return lower, upper

    def deactivate(self) -> None:
        """Forget the captured ``init`` bounds, so the next :meth:`level` re-activates.

        A stack that starts again (a new task stack, or one resumed after a hold) calls
        this, so its ``init`` targets are captured anew from the configuration at that
        moment instead of where the task was first started.
        """
        self._active_lower = None
        self._active_upper = None

    def level(self, kin: Kinematics, t: float) -> Level:
        """Build this task's :class:`Level` at task time ``t`` in [s]."""
        if self._active_lower is None:  # the first build after the stack started
            if self._value_is_computed:
                self._capture(kin)
                alpha, A, gamma = self.compute(kin)
                self._activate_bounds(kin, alpha)
            else:
                self.activate(kin)
                alpha, A, gamma = self.compute(kin)
        else:
            alpha, A, gamma = self.compute(kin)
        lower, upper = self._active_lower, self._active_upper
        if lower is None or upper is None:
            lower, upper = self._active_bounds()  # raises: not active
        lo, lo_rate = lower.evaluate(t)
        ff = self._ff
        if self.equality:
            hi = hi_ff = None
            if self._zero_gain:  # its upper side separately, as an inequality's
                hi, hi_ff = lo, lo_rate if ff is None else ff
        else:
            hi, hi_rate = upper.evaluate(t)
            hi_ff = hi_rate if ff is None else ff
        kd = None
        if self.velocity_gain:
            kd = self.velocity_gain * self.compute_measured_rate(kin)
        beta_lo, beta_hi = kin.kernels.task_bounds(
            self.gain, alpha, lo, lo_rate if ff is None else ff, hi, hi_ff,
            gamma if self.compensate_velocity and self.has_gamma else None, kd,
            self._zero_gain)
        return Level(self.name, A, beta_lo, beta_hi, self.equality)

    def bounds_at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Return ``(lower, upper)`` task bounds at task time t (after activation)."""
        lower, upper = self._active_bounds()
        return lower.evaluate(t)[0], upper.evaluate(t)[0]

    def __repr__(self) -> str:
        return f'{type(self).__name__}({self.name!r}, dim={self.dim})'
