"""The small interface every emulated (or real) robot backend implements (docs/STYLE.md rule 5).

A backend is driven by four calls: :meth:`RobotInterface.reset`, :meth:`~RobotInterface.
read_state`, :meth:`~RobotInterface.write_command` and :meth:`~RobotInterface.close`; a
simulated backend also advances time with :meth:`~RobotInterface.step` /
:meth:`~RobotInterface.step_until`. Commands are virtual joint positions q_v held between
updates (zero-order hold), exactly what an FRI-like interface receives.

Sign conventions (all wrenches are ``[fx, fy, fz, tx, ty, tz]``):

- ``tau_ext_est`` and ``contact_wrench`` are what the environment exerts ON the robot
  (an object pressing down on the tool gives a negative ``fz``).
- ``ft_wrench`` is the raw sensor reading: what the sensor's parent body exerts on the
  subtree below the sensor (tool weight included), in the sensor frame, moment about the
  sensor origin — what a real wrist F/T sensor reports up to its sign convention.
- ``ft_external`` is the same reading with the tool weight removed, mapped to what the
  environment exerts on the tool, in the robot base frame, moment about the chain frame
  (e.g. the tool tip). This is the ``h`` the Cartesian admittance law reacts to.
"""

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, TypeVar

import numpy as np

from ifc_spg.errors import ParameterError

__all__ = ['FakeInterface', 'RobotInterface', 'State', 'check_fri_delay']


@dataclass(frozen=True)
class State:
    """One sample of the robot (and scene) state.

    Attributes:
        t: Simulation time in [s].
        joint_names: Robot joint names, the order of every joint vector.
        q: Measured joint positions in [rad] (or [m] for prismatic joints).
        qd: Measured joint velocities in [rad/s].
        tau_measured: Joint torque the interface applies (motor side) in [Nm].
        tau_ext_est: External joint torque (environment on robot) in [Nm], FRI-like.
        q_v: The virtual joint positions currently held in [rad].
        ft_wrench: Chain id -> raw F/T sensor wrench (sensor frame) in [N, Nm].
        ft_frames: Chain id -> name of the F/T sensor frame (site).
        ft_external: Chain id -> tool-weight-compensated external wrench at the chain frame,
            base frame, in [N, Nm].
        contact_wrench: Ground-truth wrench the environment exerts on the tool (contacts and
            grasp constraints, pushes excluded), about the tool frame, base frame [N, Nm].
        env_joint_names: Scene mechanism joint names (drawer, door, crank).
        env_q: Scene mechanism positions in [m] or [rad].
        env_qd: Scene mechanism velocities in [m/s] or [rad/s].
        missed_commands: Command periods that passed without a new command (q_v held).
    """

    t: float
    joint_names: tuple[str, ...]
    q: np.ndarray
    qd: np.ndarray
    tau_measured: np.ndarray
    tau_ext_est: np.ndarray
    q_v: np.ndarray
    ft_wrench: dict[str, np.ndarray] = field(default_factory=dict)
    ft_frames: dict[str, Any] = field(default_factory=dict)
    ft_external: dict[str, np.ndarray] = field(default_factory=dict)
    contact_wrench: np.ndarray = field(default_factory=lambda: np.zeros(6))
    env_joint_names: tuple[str, ...] = ()
    env_q: np.ndarray = field(default_factory=lambda: np.zeros(0))
    env_qd: np.ndarray = field(default_factory=lambda: np.zeros(0))
    missed_commands: int = 0


_Interface = TypeVar('_Interface', bound='RobotInterface')


class RobotInterface:
    """Base class of the robot backends: the simulation and the fake."""

    joint_names: tuple[str, ...] = ()
    dt = 0.001

    def reset(self, q0: Sequence[float] | np.ndarray | None = None) -> None:
        """Reset to joint positions ``q0`` in [rad] (default: the home pose), at rest."""
        raise NotImplementedError

    def read_state(self) -> State:
        """Return the current :class:`State`."""
        raise NotImplementedError

    def write_command(self, q_v: Sequence[float] | np.ndarray,
                      qd_v: Sequence[float] | np.ndarray | None = None) -> None:
        """Set the virtual joint positions q_v in [rad] (held until the next command).

        Args:
            q_v: Virtual joint positions in [rad], one per joint in ``joint_names``.
            qd_v: Virtual joint velocities in [rad/s] (optional feed-forward).
        """
        raise NotImplementedError

    def step(self, n: int = 1) -> None:
        """Advance ``n`` physics steps of ``dt`` seconds."""
        raise NotImplementedError

    def step_until(self, t: float) -> None:
        """Advance whole physics steps until the time is >= ``t`` - dt/2 (t in [s])."""
        n = round((t - self.read_time()) / self.dt)
        if n > 0:
            self.step(n)

    def read_time(self) -> float:
        """Current time in [s]."""
        return self.read_state().t

    def close(self) -> None:
        """Release resources; further calls are errors."""

    def __enter__(self: _Interface) -> _Interface:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def check_vector(x: Sequence[float] | np.ndarray, n: int, what: str,
                 names: Sequence[str] = ()) -> np.ndarray:
    """Return ``x`` as a float array of length ``n`` or raise :class:`ParameterError`."""
    a = np.asarray(x, dtype=float).reshape(-1)
    if a.shape != (n,):
        raise ParameterError(f'{what} must have {n} entries ({", ".join(names)}), got '
                             f'{a.shape[0]}')
    if not np.all(np.isfinite(a)):
        raise ParameterError(f'{what} must be finite, got {a.tolist()}')
    return a


def check_fri_delay(value: Any, where: str = 'fri_delay') -> int:
    """Return ``value`` as an FRI delay in periods, or raise :class:`ParameterError`.

    Args:
        value: Whole number of FRI (command) periods >= 0 (``True``/``1.5``/``-1`` are errors).
        where: What to call the value in the message (a scenario names its file).
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise ParameterError(f'{where} must be a whole number of FRI periods >= 0 (0: the '
                             f'command acts in the period it is sent, 1: one period later), '
                             f'got {value!r}')
    return int(value)


class FakeInterface(RobotInterface):
    """A MuJoCo-free backend for unit tests: each joint is a critically damped spring.

    q follows q_v as ``q̈ = ω²(q_v − q) − 2ω q̇`` (exact discretisation is not needed; the
    step is semi-implicit Euler), torques are ``K (q_v − q)``. Deterministic.

    Args:
        joint_names: Joint names.
        stiffness: Joint stiffness K in [Nm/rad] for ``tau_measured``.
        omega: Bandwidth ω of the joint response in [rad/s].
        dt: Step in [s].
    """

    def __init__(self, joint_names: Sequence[str], stiffness: float | Sequence[float] = 200.0,
                 omega: float = 30.0, dt: float = 0.001) -> None:
        self.joint_names = tuple(joint_names)
        n = len(self.joint_names)
        self._k = np.broadcast_to(np.asarray(stiffness, dtype=float), (n,)).copy()
        self._omega = float(omega)
        self.dt = float(dt)
        self._closed = False
        self.reset()

    def reset(self, q0: Sequence[float] | np.ndarray | None = None) -> None:
        """At rest at ``q0`` [rad] (default zeros), commanding it, at t = 0."""
        n = len(self.joint_names)
        self._q = np.zeros(n) if q0 is None else check_vector(q0, n, 'q0', self.joint_names)
        self._qd = np.zeros(n)
        self._q_v = self._q.copy()
        self._t = 0.0
        self._missed = 0

    def read_state(self) -> State:
        """The current :class:`State`."""
        self._check_open()
        n = len(self.joint_names)
        return State(t=self._t, joint_names=self.joint_names, q=self._q.copy(),
                     qd=self._qd.copy(), tau_measured=self._k * (self._q_v - self._q),
                     tau_ext_est=np.zeros(n), q_v=self._q_v.copy(),
                     missed_commands=self._missed)

    def write_command(self, q_v: Sequence[float] | np.ndarray,
                      qd_v: Sequence[float] | np.ndarray | None = None) -> None:
        """Command the virtual joint positions ``q_v`` [rad] (``qd_v`` is ignored)."""
        self._check_open()
        self._q_v = check_vector(q_v, len(self.joint_names), 'q_v', self.joint_names)

    def step(self, n: int = 1) -> None:
        """Advance ``n`` steps of ``dt``: each joint a damped spring towards q_v."""
        self._check_open()
        w = self._omega
        for _ in range(int(n)):
            acc = w * w * (self._q_v - self._q) - 2.0 * w * self._qd
            self._qd = self._qd + self.dt * acc
            self._q = self._q + self.dt * self._qd
            self._t += self.dt

    def read_time(self) -> float:
        """The simulated time [s]."""
        return self._t

    def close(self) -> None:
        """Close it; further calls raise."""
        self._closed = True

    def _check_open(self) -> None:
        if self._closed:
            raise ParameterError('this FakeInterface was closed; create a new one')
