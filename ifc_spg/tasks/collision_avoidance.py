"""Collision avoidance: an inequality task on distances of shape pairs (velocity damper).

For every listed pair closer than the influence distance d_i the level asks (Faverjon and
Tournassoud; Kanoun et al.)::

    d_dot >= -xi (d - d_s) / (d_i - d_s)

with d the signed distance at the virtual configuration q_v, d_dot = row qdot_v (the
distance Jacobian row of :class:`~ifc_spg.geometry.PairQuery`), d_s the margin and xi
[m/s] the approach speed allowed at d = d_i. The bound goes to zero as d reaches the
margin, so the virtual robot slows down and stops there (and is pushed back out where it
starts closer). The level has a fixed number of rows, min(pairs, ``max_rows``) (so the
cascade's models are prepared once per stack): the closest pairs within d_i, then zero
rows with open bounds. More pairs within d_i than rows: the farthest of them wait (they
are counted in the report, ``rows_dropped``).
"""

from __future__ import annotations

from collections.abc import Sequence
import math
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
import pinocchio as pin

from ifc_spg.errors import IfcSpgError
from ifc_spg.geometry import CollisionGeometry, Distances, PairQuery
from ifc_spg.tasks.task import Level, Task

if TYPE_CHECKING:
    from ifc_spg.kinematics import Kinematics
    from ifc_spg.model.robot_model import RobotModel

__all__ = ['DEFAULT_GAIN', 'DEFAULT_INFLUENCE', 'DEFAULT_MARGIN', 'DEFAULT_MAX_ROWS',
           'CollisionAvoidanceTask', 'DistanceReport']

DEFAULT_MARGIN = 0.01  # d_s [m]
DEFAULT_INFLUENCE = 0.10  # d_i [m]
DEFAULT_GAIN = 0.5  # xi [m/s]
DEFAULT_MAX_ROWS = 24  # rows of the level (the closest pairs within d_i)


def _pose_vector(position: Any, rotation: Any) -> np.ndarray:
    """[x, y, z, qx, qy, qz, qw] of a position and a rotation matrix."""
    quat = pin.Quaternion(np.asarray(rotation, dtype=float)).coeffs()
    return np.concatenate((np.asarray(position, dtype=float), quat))


class DistanceReport(NamedTuple):
    """The distances of one collision-avoidance task at one tick (for ``spg.info``).

    Attributes:
        task: Task name.
        groups: ``[(group name, pair indices)]``.
        names: ``[(shape a, shape b)]`` per pair.
        distances: The tick's :class:`~ifc_spg.geometry.Distances` at q_v.
        margin: d_s [m]; influence: d_i [m].
        q: The tick's measured joint positions [rad] (a copy).
        rows_dropped: Pairs within d_i that had no row (more than ``max_rows``).
        measure: ``measure(q) -> Distances`` at a measured configuration (computed only
            when :meth:`as_dict` asks, e.g. at the status rate).
    """

    task: str
    groups: list
    names: list
    distances: Distances
    margin: float
    influence: float
    q: np.ndarray | None = None
    measure: Any = None
    rows_dropped: int = 0

    def _groups(self, res: Distances) -> dict[str, Any]:
        d, exact = res.distance, res.exact
        out: dict[str, Any] = {}
        for group, idx in self.groups:
            sel = idx[exact[idx]]
            if not sel.size:
                out[group] = {'min_distance': None, 'pair': None, 'within_influence': 0}
                continue
            k = int(sel[np.argmin(d[sel])])
            out[group] = {'min_distance': float(d[k]), 'pair': list(self.names[k]),
                          'within_influence': int(np.count_nonzero(d[sel] < self.influence))}
        return out

    def as_dict(self) -> dict[str, Any]:
        """Per group: minimum distance, its pair and the pairs within d_i, at q_v and q.

        ``groups`` is at the virtual q_v (what the level constrains), ``measured`` at the
        measured q. A group whose pairs are all farther than the influence distance
        reports ``min_distance`` None (the cull did not compute them exactly).
        """
        out = {'task': self.task, 'margin': self.margin, 'influence': self.influence,
               'rows_dropped': self.rows_dropped, 'groups': self._groups(self.distances)}
        if self.measure is not None and self.q is not None:
            out['measured'] = self._groups(self.measure(self.q))
        return out


class CollisionAvoidanceTask(Task):
    """Keep listed shape pairs at least ``margin`` apart (an inequality task).

    Args:
        robot: The :class:`~ifc_spg.model.RobotModel`.
        geometry: The :class:`~ifc_spg.geometry.CollisionGeometry` (robot and obstacles).
        groups: ``[(group name, [(shape a, shape b), ...])]``; a pair listed twice is kept
            once (in its first group).
        margin: d_s [m], the distance never to come closer than (>= 0).
        influence: d_i [m] > margin: rows only for pairs closer than this.
        gain: xi [m/s] > 0, the approach speed allowed at d = d_i.
        max_rows: Rows of the level (>= 1): the closest pairs within d_i.
        name: Task name.
    """

    kind = 'collision_avoidance'
    has_gamma = False

    def __init__(self, robot: RobotModel, *, geometry: CollisionGeometry,
                 groups: Sequence[tuple[str, Sequence[tuple[int, int]]]],
                 margin: float = DEFAULT_MARGIN, influence: float = DEFAULT_INFLUENCE,
                 gain: float = DEFAULT_GAIN, max_rows: int = DEFAULT_MAX_ROWS,
                 name: str | None = None) -> None:
        margin, influence, gain = float(margin), float(influence), float(gain)
        label = name or self.kind
        if not (math.isfinite(margin) and margin >= 0):
            raise IfcSpgError(f"task '{label}': margin must be finite and >= 0 m, got {margin}")
        if not (math.isfinite(influence) and influence > margin):
            raise IfcSpgError(f"task '{label}': influence ({influence:g} m) must be finite and "
                              f'greater than margin ({margin:g} m)')
        if not (math.isfinite(gain) and gain > 0):
            raise IfcSpgError(f"task '{label}': gain must be finite and > 0 m/s, got {gain}")
        pairs: list[tuple[int, int]] = []
        index: dict[tuple[int, int], int] = {}
        self.groups: list[tuple[str, np.ndarray]] = []
        for group, group_pairs in groups:
            idx = []
            for a, b in group_pairs:
                key = (min(a, b), max(a, b))
                if key not in index:
                    index[key] = len(pairs)
                    pairs.append((int(a), int(b)))
                idx.append(index[key])
            self.groups.append((str(group), np.array(sorted(set(idx)), dtype=int)))
        if not pairs:
            raise IfcSpgError(f"task '{label}': no pairs to keep apart")
        if isinstance(max_rows, bool) or int(max_rows) != max_rows or max_rows < 1:
            raise IfcSpgError(f"task '{label}': max_rows must be an integer >= 1, got "
                              f'{max_rows!r}')
        super().__init__(robot, dim=min(len(pairs), int(max_rows)), name=name, lower=margin,
                         gain=gain / (influence - margin))
        self.geometry = geometry
        self.query = PairQuery(geometry, pairs)
        self.pairs = pairs
        self.names = [(geometry.shape_name(a), geometry.shape_name(b)) for a, b in pairs]
        self.margin, self.influence, self.xi = margin, influence, gain
        self._k = gain / (influence - margin)
        self._open = np.full(self.dim, np.inf)
        self._open.setflags(write=False)
        self.last: Distances | None = None
        self.row_pairs = np.zeros(0, dtype=int)  # the pair of each row of the last level
        self.rows_dropped = 0  # pairs within d_i without a row in the last level
        self._last_q: np.ndarray | None = None
        self._measured_query = PairQuery(geometry, pairs)  # stateless: its own data
        self._measured_data = robot.create_data()
        #: obstacle name -> its pose in its frame now: position [m] and unit quaternion
        #: (x, y, z, w), 7 values (the declared pose until :meth:`move_obstacle`)
        self.obstacle_poses = {name: _pose_vector(obs.position, obs.rotation)
                               for name, obs in geometry.declared.items()}

    def move_obstacle(self, name: str, pose: np.ndarray) -> bool:
        """Put obstacle ``name`` at ``pose`` in its declared frame from the next level on.

        Args:
            name: A declared obstacle (others are ignored: False).
            pose: Position [m] and unit quaternion (x, y, z, w) in the frame the obstacle
                was declared in (the base, or the chain frame it moves with) (7,).

        Returns:
            True if the pose changed. The cull's kept distances of the pairs with the
            obstacle are dropped (:meth:`~ifc_spg.geometry.PairQuery.move_shape`), so the
            level computes them with coal at the next tick.

        Raises:
            ParameterError: A pose too far from the frame of an obstacle fixed to a moving
                frame (:meth:`~ifc_spg.geometry.CollisionGeometry.obstacle_placement`).
        """
        old = self.obstacle_poses.get(name)
        pose = np.array(pose, dtype=float)
        if old is None or np.array_equal(old, pose):
            return False
        placement = self.geometry.obstacle_placement(name, pose)
        self.obstacle_poses[name] = pose
        shape = self.geometry.obstacles[name]
        self.query.move_shape(shape, placement)
        self._measured_query.move_shape(shape, placement)
        return True

    def _closest(self, distance: np.ndarray) -> np.ndarray:
        """Indices of the ``dim`` closest pairs (closest first)."""
        if distance.size <= self.dim:
            return np.argsort(distance, kind='stable')
        part = np.argpartition(distance, self.dim - 1)[:self.dim]
        return part[np.argsort(distance[part], kind='stable')]

    def compute_value(self, kin: Kinematics) -> np.ndarray:
        """The ``dim`` smallest signed distances at q_v [m], closest first (no cull)."""
        d = self.query.compute(kin.data(virtual=True), jacobians=False).distance
        return d[self._closest(d)]

    def compute_jacobian(self, kin: Kinematics) -> np.ndarray:
        """d(distance)/d(q_v) of the ``dim`` closest pairs (dim, n), no cull."""
        res = self.query.compute(kin.data(virtual=True))
        return res.rows[self._closest(res.distance)]

    def level(self, kin: Kinematics, t: float) -> Level:
        """The velocity damper rows at q_v: the closest pairs within d_i, then open rows."""
        query = self.query
        res, idx, A, lower = query.level(kin.data(virtual=True), self.influence, kin.q_v,
                                         self._k, self.margin, self.dim)
        self.last = res
        self._last_q = kin.q
        self.rows_dropped = max(0, idx.size - self.dim)
        if self.rows_dropped:
            d = res.distance
            idx = idx[self._closest(d[idx])]
            query.kernels.collision_level(res.rows, d, idx, self.influence, self._k,
                                          self.margin, A, lower)
        self.row_pairs = idx
        return Level(self.name, A, lower, self._open, False)

    def report(self) -> DistanceReport | None:
        """The last tick's :class:`DistanceReport` (None before the first tick)."""
        if self.last is None:
            return None
        return DistanceReport(self.name, self.groups, self.names, self.last, self.margin,
                              self.influence, None if self._last_q is None
                              else self._last_q.copy(), self._measure, self.rows_dropped)

    def slack_message(self, slack: Any) -> str:
        """Name the pair whose row the cascade could not meet (slack > 1e-6 m/s), or ''.

        The velocity box (joint limits, passivity, acceleration limit) did not allow the
        velocity the damper asks: q_v moves as the box allows (braking within the
        acceleration limit) and may come closer than the margin.
        """
        k = self.row_pairs.size
        if self.last is None or not k or slack is None:
            return ''
        s = slack if type(slack) is np.ndarray and slack.ndim == 1 \
            else np.asarray(slack, dtype=float).reshape(-1)
        for x in s[:k].tolist():  # (a loop over a list: numpy's reductions cost more here)
            if not -1e-6 <= x <= 1e-6:  # (NaN is not)
                break
        else:
            return ''
        s = abs(s[:k])
        k = int(self.row_pairs[int(s.argmax())])
        a, b = self.names[k]
        return (f"collision_avoidance '{self.name}': the velocity box cannot keep {a} and {b} "
                f'apart as asked (distance {self.last.distance[k] * 1e3:.1f} mm, margin '
                f'{self.margin * 1e3:.1f} mm, short by {s.max():.3g} m/s); q_v moves as the '
                'box allows and may come closer than the margin')

    def _measure(self, q: np.ndarray) -> Distances:
        """Distances at a measured configuration (bounding-sphere cull at d_i, no rows)."""
        data = self._measured_data
        pin.forwardKinematics(self.robot.model, data, q)
        return self._measured_query.compute(data, self.influence, jacobians=False)
