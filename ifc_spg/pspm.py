"""Passive set-point modulation: per-joint energy tanks (docs/SPEC.md §6, Sec. 4.2, Alg. C.4/C.5).

At each tick, with dq = q_v - q and the last two measurements, the energy surely
dissipated by the IFC damper in the last period is E_Dmin = (D/dT)(q_i - q_{i-1})^2 (4.78).
The set-point step delta = dT qdot_v may raise the spring energy 1/2 K dq^2 by at most
E_avail = E_r + E_Dmin + dE_shuffle, i.e. (both sides, exact; the thesis applies one)::

    -sqrt(2 E_avail / K + dq^2) - dq <= delta <= sqrt(2 E_avail / K + dq^2) - dq

After the step the tank is E_r <- min(E_max, E_avail - 1/2 K ((dq + delta)^2 - dq^2)).
Shuffling stops once the shuffled energy reaches its budget b^2, so with
c^2 = E_K(0) + E_r,init + sum(dE_shuffle) every joint satisfies -int tau qdot >= -c^2 (4.84).
Stiff (position-controlled) joints have no spring and are not modulated.

Power budget (issue 18): a stack that does work on its environment (sliding a tool, lifting
a drawer) may ask for a refill rate P [W] up to the node's ceiling ``max_power`` (0 by
default: strictly passive). Each tick, P dT is added to E_avail of the modulated joints,
emptiest tank first (water-filling of E_r + E_Dmin: the tanks below a common level are
raised to it, never above the take-off level E_r,init (E_max if that is 0); with every tank
at that level the refill is not taken), so the joints that spend energy get the budget as
soon as they need it, the budget only tops up what the damper's E_Dmin does not, and the
room up to E_max stays free for the energy the joints give back (a full tank would discard
it, and the budget would pay for it again). Then, per joint j,
-int tau_j qdot_j >= -(c_j^2 + R_j) with R_j the energy refilled into joint j, and
sum_j R_j <= int P dt: the whole robot injects at most sum_j c_j^2 + P t (the energy the
IFC damper surely dissipated, E_Dmin, is already on the left side: the port's tau includes
the damper). Between refills each tank still holds at most E_max, so the energy available
for a burst (a collision) stays bounded by n E_max whatever P and t.

:class:`StallMonitor` watches for joints whose empty tank keeps clipping the solution (the
stack asks for energy the budget does not give) and says how much power it asked for.
"""

from collections.abc import Sequence
from dataclasses import dataclass
import math
from types import ModuleType
from typing import NamedTuple

import numpy as np

from ifc_spg import kernels as _kernels
from ifc_spg.errors import ParameterError
from ifc_spg.limits.joint_limits import VelocityBox

__all__ = ['PspmConfig', 'EnergyTanks', 'StallMonitor', 'StallReport', 'stall_message']


@dataclass(frozen=True)
class PspmConfig:
    """Energy-tank parameters (per joint, in [J]).

    Attributes:
        initial_energy: E_r,init, energy in each tank at start (take-off, 4.2.2 item 4).
        max_energy: E_r,max, the ceiling.
        shuffle: dE_shuffle added per tick.
        shuffle_budget: b^2, total shuffled energy per joint after which shuffling stops.
        max_power: Ceiling [W] of the refill rate a task stack may ask for
            (``power_budget``); 0: strictly passive, a stack asking for any is rejected.
    """

    initial_energy: float = 0.5
    max_energy: float = 2.0
    shuffle: float = 0.0
    shuffle_budget: float = 0.0
    max_power: float = 0.0

    def __post_init__(self) -> None:
        for name in ('initial_energy', 'max_energy', 'shuffle', 'shuffle_budget', 'max_power'):
            v = getattr(self, name)
            unit = 'W' if name == 'max_power' else 'J'
            if not (np.isfinite(v) and v >= 0):
                raise ParameterError(f'pspm.{name} must be a finite number >= 0 [{unit}], '
                                     f'got {v!r}')
        if self.initial_energy > self.max_energy:
            raise ParameterError(f'pspm.initial_energy ({self.initial_energy} J) must not exceed '
                                 f'pspm.max_energy ({self.max_energy} J)')


class EnergyTanks:
    """Per-joint energy reservoirs of PSPM.

    Args:
        stiffness: Joint stiffness K in [Nm/rad] (n,).
        damping: Joint damping D in [Nms/rad] (n,).
        modulated: Mask of joints whose set-points are modulated (compliant joints).
        dt: SPG period in [s].
        config: :class:`PspmConfig`.
        kernels: The kernels module (default :data:`ifc_spg.kernels.active`).
    """

    def __init__(self, stiffness: np.ndarray, damping: np.ndarray, modulated: np.ndarray,
                 dt: float, config: PspmConfig = PspmConfig(), *,
                 kernels: ModuleType | None = None):
        self.K = np.asarray(stiffness, dtype=float)
        self.D = np.asarray(damping, dtype=float)
        self.mask = np.asarray(modulated, dtype=bool)
        self.dt = float(dt)
        self.config = config
        n = self.K.size
        self.energy = np.full(n, config.initial_energy)
        self.shuffled = np.zeros(n)
        self.refilled = np.zeros(n)
        self.power = 0.0
        self.dissipated_min = np.zeros(n)
        self._avail = np.zeros(n)
        self._shuffle_now = np.zeros(n)
        self._refill_now = np.zeros(n)
        self._q_prev: np.ndarray | None = None
        self.deficit = 0.0
        # constants of the 2 ms path
        self._shuffling = config.shuffle > 0.0 and config.shuffle_budget > 0.0
        self._extra = self._shuffling  # shuffle or refill added to E_avail this tick
        # the refill keeps the tanks at E_r,init at most: the room above is for the energy
        # the joints give back (a full tank would discard it and the budget pay for it again)
        self._fill_level = config.initial_energy if config.initial_energy > 0 else \
            config.max_energy
        self._D_over_dt = self.D / self.dt
        self._inv_dt = 1.0 / self.dt
        self._half_K = 0.5 * self.K
        with np.errstate(divide='ignore'):
            self._two_over_K = np.where(self.K > 0, 2.0 / self.K, 0.0)
        self._modulated = self.mask.astype(float)
        self._kernels = _kernels.resolve(kernels)

    def reset(self, q: np.ndarray) -> None:
        """Restart the tanks at ``E_r,init`` with ``q`` as the last measurement."""
        initial = self.config.initial_energy  # (finite: PspmConfig checks it)
        self._energy = np.full(self.K.size, initial)
        self._min_energy = initial if self.K.size else math.inf  # (the setter's, known here)
        self.shuffled = np.zeros(self.K.size)
        self.refilled = np.zeros(self.K.size)
        self._q_prev = np.array(q, dtype=float)

    def restore(self, q: np.ndarray, energy: np.ndarray,
                shuffled: np.ndarray | None = None) -> None:
        """Continue from given tank energies (a replay that starts mid-run).

        Continue from energies ``energy`` [J] and shuffled totals ``shuffled`` [J] with
        ``q`` [rad] as the last measurement (a replay that starts mid-run).
        """
        self.energy = np.array(energy, dtype=float)
        self.shuffled = np.zeros(self.K.size) if shuffled is None else \
            np.array(shuffled, dtype=float)
        self._q_prev = np.array(q, dtype=float)

    def power_error(self, power: float) -> str:
        """Why ``power`` [W] is not an allowed refill rate, or '' if it is (<= the ceiling)."""
        ceiling = self.config.max_power
        if power <= ceiling:
            return ''
        if ceiling == 0.0:
            return (f'power_budget {power:g} W asks the energy tanks for a refill, but this node '
                    'is strictly passive (spg_node parameter pspm.max_power = 0 W); a safety '
                    f'engineer may allow it with -p pspm.max_power:={power:g} (or more), or '
                    'remove power_budget from the stack')
        return (f'power_budget {power:g} W exceeds the ceiling of {ceiling:g} W set by the '
                f'spg_node parameter pspm.max_power; lower power_budget to <= {ceiling:g} or '
                f'raise pspm.max_power to >= {power:g}')

    def set_power(self, power: float) -> None:
        """Refill the tanks at ``power`` [W] from the next tick on (0 <= power <= ceiling).

        Raises:
            ParameterError: ``power`` is negative, not finite or above ``max_power``.
        """
        power = float(power)
        if not (math.isfinite(power) and power >= 0.0):
            raise ParameterError(f'power_budget must be a finite number >= 0 [W], got {power!r}')
        message = self.power_error(power)
        if message:
            raise ParameterError(message)
        self.power = power
        self._extra = self._shuffling or power > 0.0

    @property
    def energy(self) -> np.ndarray:
        """Energy per tank [J].

        Assign a new array to change it, not in place: the smallest entry is kept alongside
        (:meth:`any_empty`).
        """
        return self._energy

    @energy.setter
    def energy(self, value: np.ndarray) -> None:
        self._energy = value
        v = np.asarray(value, dtype=float)
        v = v[~np.isnan(v)]  # (as (energy <= tol).any(): a NaN tank is not empty)
        self._min_energy = float(v.min()) if v.size else math.inf

    def any_empty(self, tol: float = 1e-9) -> bool:
        """Whether any tank holds at most ``tol`` [J] (a float compare: the 2 ms path)."""
        return self._min_energy <= tol

    def empty(self, tol: float = 1e-9) -> np.ndarray:
        """Mask of the modulated joints whose tank is empty (<= ``tol`` [J]) after the tick."""
        return (self.energy <= tol) & self.mask

    def requested_power(self, q: np.ndarray, q_v: np.ndarray, qdot_v: np.ndarray
                        ) -> np.ndarray:
        """Power [W] per joint a step would take from the tanks.

        Power [W] per joint the step ``qdot_v`` [rad/s] from ``q_v`` would take from the
        tank this tick beyond what the IFC damper returned (E_Dmin): the spring energy it
        adds, 1/2 K ((dq + dT qdot_v)^2 - dq^2), minus E_Dmin, over dT (0 for stiff
        joints).
        """
        dq = q_v - q
        dE = self._half_K * ((dq + self.dt * qdot_v) ** 2 - dq * dq) - self.dissipated_min
        return np.where(self.mask, dE * self._inv_dt, 0.0)

    @property
    def available(self) -> np.ndarray:
        """E_avail of this tick's bounds per joint in [J] (read-only view)."""
        view = self._avail.view()
        view.setflags(write=False)
        return view

    def bounds(self, q: np.ndarray, q_v: np.ndarray) -> VelocityBox:
        """Return the passivity :class:`VelocityBox` for this tick (contains 0).

        Args:
            q: Measured joint positions in [rad] at this tick.
            q_v: Virtual joint positions in [rad] before this tick's step.
        """
        q_prev = self._q_prev
        if q_prev is None:
            q_prev = self._q_prev = np.array(q, dtype=float)
        shuffle = None
        if self._extra:  # the refill tops up what this tick's E_Dmin leaves
            shuffle = self._added(self._D_over_dt * (q - q_prev) ** 2
                                  if self.power > 0.0 else None)
        lower, upper, self.dissipated_min, self._avail = self._kernels.pspm_bounds(
            q, q_v, q_prev, self.energy, shuffle, self._D_over_dt, self._two_over_K,
            self._inv_dt, self._modulated)
        q_prev[:] = q  # the next tick's q_prev (the kernel only reads it)
        return VelocityBox(lower, upper)

    def _added(self, dissipated):
        """This tick's shuffled plus refilled energy per joint in [J].

        This tick's shuffled plus refilled energy per joint in [J] (``dissipated``: this
        tick's E_Dmin, which counts as already in the tank when the refill is shared).
        """
        if self._shuffling:
            room = np.maximum(self.config.shuffle_budget - self.shuffled, 0.0)
            self._shuffle_now = np.minimum(self.config.shuffle, room)
            added = self._shuffle_now.copy()
        else:
            added = np.zeros(self.K.size)
        if self.power > 0.0:
            room = self._water_fill(self.power * self.dt, self.energy + dissipated)
            self._refill_now = room
            added += room
        return added

    def _water_fill(self, amount, e):
        """Share a refill among the modulated tanks, emptiest first.

        Share ``amount`` [J] among the modulated tanks with energies ``e`` [J], emptiest
        first: the tanks below a common level are raised to it (never above the fill level
        E_r,init, or E_max if that is 0); returns the refill per joint.
        """
        idx = np.flatnonzero(self.mask)
        order = idx[np.argsort(e[idx], kind='stable')]
        levels = e[order]
        filled = np.cumsum(levels)
        k = np.arange(1, levels.size + 1)
        level = (amount + filled) / k              # the level if the k emptiest are raised
        nxt = np.append(levels[1:], np.inf)
        j = int(np.argmax(level <= nxt))           # the first k whose level fits below the next
        level = min(float(level[j]), self._fill_level)
        refill = np.zeros(e.size)
        refill[order[:j + 1]] = np.maximum(level - levels[:j + 1], 0.0)
        return refill

    def update(self, q: np.ndarray, q_v: np.ndarray, qdot_v: np.ndarray) -> np.ndarray:
        """Book the applied step into the tanks (Alg. C.5 lines 21-25).

        Args:
            q: Measured joint positions in [rad] at this tick.
            q_v: Virtual joint positions before the step in [rad].
            qdot_v: Applied virtual joint velocity in [rad/s].
        """
        e, dEk, e_min = self._kernels.pspm_update(
            q, q_v, qdot_v, self._avail, self._half_K, self.dt, self.config.max_energy,
            self._modulated, self.energy)
        if not e_min >= 0.0:  # NaN (inf - inf on absurd measurements) or round-off below 0
            e[np.isnan(e)] = 0.0  # an overflow empties the tank
            # only round-off can make e negative (the step was bounded by E_avail); record it
            self.deficit = float(max(0.0, -e.min()))
            np.maximum(e, 0.0, out=e)
            self.energy = e
        else:
            self.deficit = 0.0
            self._energy, self._min_energy = e, e_min  # (the kernel's minimum: no reduction)
        if self._shuffling:
            self.shuffled += np.where(self.mask, self._shuffle_now, 0.0)
        if self.power > 0.0:
            self.refilled += self._refill_now
        return dEk


class StallReport(NamedTuple):
    """Joints whose empty tank keeps clipping the stack's solution (see :class:`StallMonitor`).

    Attributes:
        joints: Indices of the stalled joints (model order).
        requested_power: Power [W] the stack asked of each stalled joint's tank beyond what
            the IFC damper returned (same order as ``joints``).
        total_power: Sum of ``requested_power`` [W].
        robot_power: The rate [W] at which all the tanks together were drained (beyond the
            damper's refill) while they had energy: what the whole stack spends running.
        power_budget: The refill rate in effect [W].
        max_power: The node's ceiling ``pspm.max_power`` [W].
        since: Task time [s] at which the stall was first reported.
    """

    joints: tuple
    requested_power: tuple
    total_power: float
    robot_power: float
    power_budget: float
    max_power: float
    since: float

    def suggestion(self) -> str:
        """The setting that would give the stack the power it asks for.

        The setting that would give the stack the power it asks for: twice the larger of
        the request, the robot's running consumption and the budget in effect (these are
        lower bounds; a stall reported again under the new budget asks for twice that).
        """
        # the request is measured at the stalled state (the joint barely moves, so less than
        # moving will take) and the refill goes to whichever tank is emptiest: ask for twice
        # the larger of the request, what the whole robot spent running, and the budget
        need = _round_up(2.0 * max(self.total_power, self.robot_power, self.power_budget))
        fix = f"declare 'power_budget: {need:g}' [W] in the task stack"
        if need > self.max_power:
            fix += f' and raise the spg_node parameter pspm.max_power to >= {need:g} W'
        return fix


def _round_up(x):
    """``x`` rounded up to 2 significant digits (0.0123 -> 0.013, 1.23 -> 1.3)."""
    if not x > 0:
        return 0.0
    scale = 10.0 ** (np.floor(np.log10(x)) - 1)
    return float(np.ceil(x / scale - 1e-9) * scale)


class StallMonitor:
    """Detects a stall: an empty tank that clips the stack's solution for more than a moment.

    Each tick :meth:`observe` looks at the joints whose tank ended the tick empty (the step
    used all the available energy). Their exponential average (time constant
    ``time_constant``) above 1/2 — about 0.35 s of an empty tank — makes the joint a
    *candidate*; then, every ``probe_every`` ticks, the SPG solves the cascade once more
    without the passivity bound and :meth:`observe` gets the power [W] each joint's tank
    would have had to give for that solution (beyond what the IFC damper returned). A
    candidate asking for more than ``min_power`` [W] (averaged over probes) is stalled. The
    power reported is the larger of that request and the rate at which the joint drained its
    tank while it still had energy (averaged over ``drain_time`` [s], frozen while the tank
    is empty): a stalled joint barely moves, so its request alone understates what running
    will take. The report also gives the drain rate of all the tanks together
    (``robot_power``). The first stall of an episode (a stack activation or a restart) is
    flagged in :attr:`new` for one tick, so callers log it once; it is flagged again only
    when joints not reported before in the episode stall (at most once per joint and
    episode). While no tank is empty a tick costs two comparisons; the drain rates are
    booked every ``probe_every`` ticks from the tanks' energies and refills.

    Args:
        tanks: The :class:`EnergyTanks` to watch.
        time_constant: Of the empty-tank average in [s].
        probe_every: Ticks between the extra solves while a joint is a candidate (and
            between drain samples).
        min_power: Requested power [W] below which a candidate is not stalled.
        drain_time: Averaging time of the drain rates in [s].
    """

    def __init__(self, tanks: EnergyTanks, time_constant: float = 0.5, probe_every: int = 25,
                 min_power: float = 1e-3,
                 drain_time=5.0):
        self.tanks = tanks
        self.n = tanks.K.size
        dt = tanks.dt
        self._alpha = min(1.0, dt / float(time_constant))
        self.probe_every = int(probe_every)
        self._window = self.probe_every * dt
        self._alpha_drain = min(1.0, self._window / float(drain_time))
        self.min_power = float(min_power)
        # the averages, written in place (reset() zeroes them: a first tick resets twice)
        self._empty = np.zeros(self.n)
        self._power = np.zeros(self.n)
        self._drain = np.zeros(self.n)
        self.reset()

    def reset(self) -> None:
        """A new episode: forget the averages; the next stall is reported again."""
        self._empty.fill(0.0)
        self._active = False            # some joint's empty average is not (yet) zero
        self._power.fill(0.0)
        self._drain.fill(0.0)
        self._mark: tuple | None = None  # (tank energy, refilled + shuffled) of the last sample
        self._ticks = 0
        self.report: StallReport | None = None
        self.new = False
        self._reported: set[int] = set()

    @property
    def wants_probe(self) -> bool:
        """True when this tick's caller should solve without the passivity bound."""
        return self._active and self._ticks % self.probe_every == 0 and bool(
            np.any(self._empty > 0.5))

    def _sample_drain(self, candidate):
        # energy that left the tanks beyond the damper's refill: E_before + refill + shuffle
        # - E_after, per joint, over the window (booked while the joint is not a candidate)
        tanks = self.tanks
        mark = (tanks.energy.copy(), tanks.refilled + tanks.shuffled)
        if self._mark is not None:
            drain = (self._mark[0] - mark[0] + mark[1] - self._mark[1]) / self._window
            step = self._alpha_drain * (drain - self._drain)
            if candidate is not None:
                step[candidate] = 0.0
            self._drain += step
        self._mark = mark

    def observe(self, requested_power: np.ndarray | None = None, *,
                task_time: float = 0.0) -> None:
        """Book one tick (after the tanks booked the step).

        Args:
            requested_power: Per joint [W] the stack asked for beyond the damper's refill
                (only on probe ticks, else None).
            task_time: Task time of this tick [s].
        """
        self._ticks += 1
        self.new = False
        tanks = self.tanks
        sample = self._ticks % self.probe_every == 0
        if not self._active:
            if not tanks.any_empty(1e-9):  # the usual tick: no tank is empty
                if sample:
                    self._sample_drain(None)
                return
            self._active = True
        self._empty += self._alpha * (tanks.empty() - self._empty)
        candidate = self._empty > 0.5
        if sample:
            self._sample_drain(candidate)
        if requested_power is not None:
            p = np.where(candidate, np.maximum(requested_power, 0.0), 0.0)
            self._power += 0.3 * (p - self._power)
        self._power[~candidate] = 0.0
        stalled = np.flatnonzero(candidate & (self._power > self.min_power))
        if not stalled.size:
            self.report = None
            if self._empty.max() < 1e-6:
                self._empty[:] = 0.0
                self._active = False
            return
        joints = tuple(int(j) for j in stalled)
        power = tuple(float(max(self._power[j], self._drain[j])) for j in stalled)
        since = task_time if self.report is None else self.report.since
        robot = max(0.0, float(self._drain.sum()))
        self.report = StallReport(joints, power, float(sum(power)), robot, float(tanks.power),
                                  float(tanks.config.max_power), float(since))
        if not self._reported.issuperset(joints):  # first stall, or other joints stall
            self._reported.update(joints)
            self.new = True


def stall_message(report: StallReport, joint_names: Sequence[str]) -> str:
    """One line for the log and ``spg/status``: which joints, how much power, the fix."""
    names = [joint_names[j] for j in report.joints]
    each = ', '.join(f'{n} {p:.3g}' for n, p in zip(names, report.requested_power))
    return (f"PSPM stall: the energy tanks of {', '.join(names)} are empty and clip the task "
            f'stack since task time {report.since:.2f} s (the tasks slow down or stop); the '
            f'stack asks for {report.total_power:.3g} W ({each} W), the whole robot spent '
            f'{report.robot_power:.3g} W while its tanks had energy, with a power budget of '
            f'{report.power_budget:g} W (ceiling pspm.max_power {report.max_power:g} W); '
            f'{report.suggestion()}')
