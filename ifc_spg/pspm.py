"""Passive set-point modulation: per-joint energy tanks (SPEC 6, Sec. 4.2, Alg. C.4/C.5).

At each tick, with dq = q_v - q and the last two measurements, the energy surely
dissipated by the IFC damper in the last period is E_Dmin = (D/dT)(q_i - q_{i-1})^2 (4.78).
The set-point step delta = dT qdot_v may raise the spring energy 1/2 K dq^2 by at most
E_avail = E_r + E_Dmin + dE_shuffle, i.e. (both sides, exact; the thesis applies one)::

    -sqrt(2 E_avail / K + dq^2) - dq <= delta <= sqrt(2 E_avail / K + dq^2) - dq

After the step the tank is E_r <- min(E_max, E_avail - 1/2 K ((dq + delta)^2 - dq^2)).
Shuffling stops once the shuffled energy reaches its budget b^2, so with
c^2 = E_K(0) + E_r,init + sum(dE_shuffle) every joint satisfies -int tau qdot >= -c^2 (4.84).
Stiff (position-controlled) joints have no spring and are not modulated.
"""

from dataclasses import dataclass

import numpy as np

from ifc_spg import native
from ifc_spg.errors import ParameterError
from ifc_spg.limits.joint_limits import VelocityBox

__all__ = ['PspmConfig', 'EnergyTanks']


@dataclass(frozen=True)
class PspmConfig:
    """Energy-tank parameters (per joint, in [J]).

    Attributes:
        initial_energy: E_r,init, energy in each tank at start (take-off, 4.2.2 item 4).
        max_energy: E_r,max, the ceiling.
        shuffle: dE_shuffle added per tick.
        shuffle_budget: b^2, total shuffled energy per joint after which shuffling stops.
    """

    initial_energy: float = 0.5
    max_energy: float = 2.0
    shuffle: float = 0.0
    shuffle_budget: float = 0.0

    def __post_init__(self):
        for name in ('initial_energy', 'max_energy', 'shuffle', 'shuffle_budget'):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ParameterError(f'pspm.{name} must be a finite number >= 0 [J], got {v!r}')
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
    """

    def __init__(self, stiffness, damping, modulated, dt, config=PspmConfig()):
        self.K = np.asarray(stiffness, dtype=float)
        self.D = np.asarray(damping, dtype=float)
        self.mask = np.asarray(modulated, dtype=bool)
        self.dt = float(dt)
        self.config = config
        n = self.K.size
        self.energy = np.full(n, config.initial_energy)
        self.shuffled = np.zeros(n)
        self.dissipated_min = np.zeros(n)
        self._avail = np.zeros(n)
        self._shuffle_now = np.zeros(n)
        self._q_prev = None
        self.deficit = 0.0
        # constants of the 2 ms path
        self._all = bool(self.mask.all())
        self._fixed = np.flatnonzero(~self.mask)  # joints without modulation (stiff)
        self._shuffling = config.shuffle > 0.0 and config.shuffle_budget > 0.0
        self._D_over_dt = self.D / self.dt
        self._inv_dt = 1.0 / self.dt
        self._minus_inv_dt = -self._inv_dt
        self._half_K = 0.5 * self.K
        with np.errstate(divide='ignore'):
            self._two_over_K = np.where(self.K > 0, 2.0 / self.K, 0.0)
        self._modulated = self.mask.astype(float)
        self._native = native.module  # C kernels (ifc_spg.native), or None: numpy below

    def reset(self, q):
        """Restart the tanks at ``E_r,init`` with ``q`` as the last measurement."""
        self.energy = np.full(self.K.size, self.config.initial_energy)
        self.shuffled = np.zeros(self.K.size)
        self._q_prev = np.array(q, dtype=float)

    def bounds(self, q, q_v):
        """Return the passivity :class:`VelocityBox` for this tick (contains 0).

        Args:
            q: Measured joint positions in [rad] at this tick.
            q_v: Virtual joint positions in [rad] before this tick's step.
        """
        if self._q_prev is None:
            self._q_prev = np.array(q, dtype=float)
        if self._native is not None:
            shuffle = self._shuffle() if self._shuffling else None
            lower, upper, self.dissipated_min, self._avail = self._native.pspm_bounds(
                q, q_v, self._q_prev, self.energy, shuffle, self._D_over_dt,
                self._two_over_K, self._inv_dt, self._modulated)
            return VelocityBox(lower, upper)
        step = q - self._q_prev
        step *= step
        step *= self._D_over_dt
        self.dissipated_min = step
        self._q_prev[:] = q
        if self._shuffling:
            self._avail = self.energy + step + self._shuffle()
        else:
            self._avail = self.energy + step
        dq = q_v - q
        r = self._avail * self._two_over_K
        r += dq * dq
        np.sqrt(r, out=r)
        upper = r - dq
        upper *= self._inv_dt
        r += dq
        r *= self._minus_inv_dt
        lower = r
        if not self._all:
            lower[self._fixed] = -np.inf
            upper[self._fixed] = np.inf
        return VelocityBox(lower, upper)

    def _shuffle(self):
        """This tick's shuffled energy per joint (capped by what is left of the budget)."""
        room = np.maximum(self.config.shuffle_budget - self.shuffled, 0.0)
        self._shuffle_now = np.minimum(self.config.shuffle, room)
        return self._shuffle_now

    def update(self, q, q_v, qdot_v):
        """Book the applied step into the tanks (Alg. C.5 lines 21-25).

        Args:
            q: Measured joint positions in [rad] at this tick.
            q_v: Virtual joint positions before the step in [rad].
            qdot_v: Applied virtual joint velocity in [rad/s].
        """
        if self._native is not None:
            e, dEk, e_min = self._native.pspm_update(
                q, q_v, qdot_v, self._avail, self._half_K, self.dt, self.config.max_energy,
                self._modulated, self.energy)
        else:
            dq = q_v - q
            new = qdot_v * self.dt
            new += dq
            new *= new
            dq *= dq
            new -= dq
            dEk = new
            dEk *= self._half_K
            e = self._avail - dEk
            np.minimum(e, self.config.max_energy, out=e)
            if not self._all:
                e[self._fixed] = self.energy[self._fixed]
            e_min = e.min()
        if not e_min >= 0.0:  # NaN (inf - inf on absurd measurements) or round-off below 0
            e[np.isnan(e)] = 0.0  # an overflow empties the tank
            # only round-off can make e negative (the step was bounded by E_avail); record it
            self.deficit = float(max(0.0, -e.min()))
            np.maximum(e, 0.0, out=e)
        else:
            self.deficit = 0.0
        self.energy = e
        if self._shuffling:
            self.shuffled += np.where(self.mask, self._shuffle_now, 0.0)
        return dEk
