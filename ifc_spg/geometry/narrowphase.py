"""The narrowphase of a pair query: coal distances and witness points of many shape pairs.

Two implementations with the same methods, chosen once at import (:data:`native`) and used by
each new :class:`~ifc_spg.geometry.PairQuery`:

- ``ifc_spg.kernels._coal_native.Pairs`` (C++, built from ``_coal_native.cpp`` at install
  time against the coal and pinocchio of the cmeel wheels): all the pairs of a tick in one
  call, on the very coal shapes of the pinocchio ``GeometryModel``;
- :class:`PinocchioPairs`: pinocchio's Python bindings, ``computeDistance`` per pair (~1.5 us
  a pair, ~0.4 us per witness point read, against coal's ~0.3 us of work).

Both compute the same numbers: pinocchio's placement (oMg = oMi * placement) and
``computeDistance`` with the same request (signed, GJK tolerance, no cached guess). The C++
module is refused (the Python path runs, :func:`describe` says why) where it was not built,
where ``IFC_SPG_NATIVE=0`` is set, where it is stale (another :data:`API` than this file's) or
where it was built against another coal or pinocchio than the ones imported (its C++ objects
would not be theirs).

Methods (``data``: a pinocchio ``Data`` after ``forwardKinematics`` at the configuration):

- ``narrowphase(data, near, influence, eps, distance, point_a, point_b, normal) -> within``
- ``distances(data, out)``: every pair's distance
- ``gaps(data, out)``: the bounding spheres' gaps (the cull without coal)
- ``move_shape(shape, rotation, translation)``: a shape's placement in its joint's frame

and, in the C++ module only, ``level(...)``: the cull across calls, the narrowphase, the rows
and the velocity damper level of :meth:`~ifc_spg.geometry.PairQuery.level` in one call.
"""

from __future__ import annotations

from collections.abc import Sequence
import importlib
import os
from types import ModuleType
from typing import Any
import warnings

import coal
import numpy as np
import pinocchio as pin

__all__ = ['API', 'PinocchioPairs', 'describe', 'native', 'pairs', 'refused']

#: The ``API`` the C++ module must have (its ``kApi``; bumped with its signatures).
API = 2

#: Why the C++ module is not used ('' where it is).
refused = ''


def _load() -> ModuleType | None:
    global refused
    if os.environ.get('IFC_SPG_NATIVE', '1').strip() == '0':
        refused = 'IFC_SPG_NATIVE=0'
        return None
    try:
        module = importlib.import_module('ifc_spg.kernels._coal_native')
    except ImportError as exc:
        refused = (f'ifc_spg.kernels._coal_native was not built ({exc}): reinstall with a C++ '
                   'compiler and the cmeel-eigen wheel, ./run setup')
        return None
    built = (getattr(module, 'API', None), getattr(module, 'COAL_VERSION', None),
             getattr(module, 'PINOCCHIO_VERSION', None))
    if built != (API, coal.__version__, pin.__version__):
        refused = (f'ifc_spg.kernels._coal_native is a stale or mismatched build (API '
                   f'{built[0]}, coal {built[1]}, pinocchio {built[2]}; this package wants API '
                   f'{API}, coal {coal.__version__}, pinocchio {pin.__version__}): rebuild it '
                   'with ./run setup or pip install -e .')
        return None
    refused = ''
    return module


#: The C++ module, or None where it is refused (:data:`refused` says why).
native: ModuleType | None = _load()


def describe() -> str:
    """Which narrowphase new pair queries use, and why."""
    if native is not None:
        return f'C++ on coal {native.COAL_VERSION} (one call per tick)'
    return f"pinocchio's Python bindings ({refused})"


class PinocchioPairs:
    """The narrowphase through pinocchio's Python bindings (:mod:`ifc_spg.geometry.narrowphase`).

    Args:
        model: The ``GeometryModel`` of the shapes (copied: this object owns its pairs).
        robot_model: The pinocchio ``Model`` the shapes' joints are in.
        pairs: ``[(a, b)]`` shape indices.
        radius: Bounding sphere radius per shape [m] (inf: unbounded).
        gjk_tolerance: GJK/EPA tolerance [m].
    """

    def __init__(self, model: pin.GeometryModel, robot_model: pin.Model,
                 pairs: Sequence[tuple[int, int]], radius: np.ndarray,
                 gjk_tolerance: float) -> None:
        gm = model.copy()
        gm.removeAllCollisionPairs()
        for a, b in pairs:
            gm.addCollisionPair(pin.CollisionPair(int(a), int(b)))
        #: the ``GeometryModel`` (its own copy) and ``GeometryData`` of the pairs
        self.model = gm
        self.data = pin.GeometryData(gm)
        for req in self.data.distanceRequests:
            req.enable_signed_distance = True
            req.gjk_tolerance = gjk_tolerance  # coal's default 1e-6 m leaves ~2e-7 m noise
            # pinocchio starts GJK from the pair's last solution: the result then depends,
            # within the GJK tolerance, on what the query computed before (rows by up to
            # ~5e-6 where the witness points are not unique, e.g. a capsule parallel to a
            # cylinder), and a replay restored mid-run would not repeat the live ticks
            with warnings.catch_warnings():
                warnings.simplefilter('ignore', DeprecationWarning)  # coal 3 renamed it
                req.enable_cached_gjk_guess = False
        self._robot_model = robot_model
        self._m = len(pairs)
        self._ia = np.array([a for a, _ in pairs], dtype=int)
        self._ib = np.array([b for _, b in pairs], dtype=int)
        self._rsum = radius[self._ia] + radius[self._ib]
        self._unbounded = ~np.isfinite(self._rsum)
        self._any_unbounded = bool(self._unbounded.any())
        self._rsum[self._unbounded] = 0.0

    def move_shape(self, shape: int, rotation: np.ndarray, translation: np.ndarray) -> None:
        """Place shape ``shape`` at (rotation, translation) in its joint's frame."""
        self.model.geometryObjects[shape].placement = pin.SE3(rotation, translation)

    def _place(self, data: pin.Data) -> None:
        pin.updateGeometryPlacements(self._robot_model, data, self.model, self.data)

    def gaps(self, data: pin.Data, out: np.ndarray) -> None:
        """The bounding spheres' gaps of every pair into ``out`` (-inf where unbounded)."""
        self._place(data)
        c = np.array([M.translation for M in self.data.oMg])
        diff = c[self._ia] - c[self._ib]
        out[:] = np.sqrt(np.einsum('ij,ij->i', diff, diff)) - self._rsum
        if self._any_unbounded:
            out[self._unbounded] = -np.inf

    def distances(self, data: pin.Data, out: np.ndarray) -> None:
        """The coal distances of every pair into ``out``."""
        self._place(data)
        gm, gd, distance = self.model, self.data, pin.computeDistance
        out[:] = [distance(gm, gd, k).min_distance for k in range(self._m)]

    def narrowphase(self, data: pin.Data, near: Any, influence: float, eps: float,
                    distance: np.ndarray, point_a: np.ndarray, point_b: np.ndarray,
                    normal: np.ndarray) -> np.ndarray:
        """The coal distances of the pairs ``near``, witness points of those within ``influence``.

        Writes ``distance[p]`` for each p in ``near``; for the pairs with distance <=
        influence (returned, ascending as in ``near``) the witness points ``point_a[p]``,
        ``point_b[p]`` in the base frame and, where distance <= ``eps``, coal's unit normal
        ``normal[p]`` (from a to b).
        """
        self._place(data)
        gm, gd, compute = self.model, self.data, pin.computeDistance
        within: list[int] = []
        found: list[np.ndarray] = []  # p_a, p_b of each pair within
        keep, point = within.append, found.append
        for p in np.asarray(near).tolist():
            res = compute(gm, gd, p)
            d = res.min_distance
            distance[p] = d
            if d <= influence:
                keep(p)
                point(res.getNearestPoint1())
                point(res.getNearestPoint2())
                if d <= eps:  # touching or overlapping: coal's normal
                    normal[p] = res.normal
        if within:
            point_a[within] = found[0::2]
            point_b[within] = found[1::2]
        return np.array(within, dtype=np.intp)


def pairs(model: pin.GeometryModel, robot_model: pin.Model, pairs: Sequence[tuple[int, int]],
          radius: np.ndarray, gjk_tolerance: float) -> Any:
    """The narrowphase of ``pairs`` (arguments of :class:`PinocchioPairs`).

    The C++ module's where :data:`native` is not None, else a :class:`PinocchioPairs`. The
    shapes' placements are the model's now.
    """
    if native is None:
        return PinocchioPairs(model, robot_model, pairs, radius, gjk_tolerance)
    objs = model.geometryObjects
    return native.Pairs([o.geometry for o in objs], np.array([o.parentJoint for o in objs]),
                        np.array([o.placement.rotation for o in objs]),
                        np.array([o.placement.translation for o in objs]),
                        np.asarray(radius, dtype=float),
                        np.array(pairs, dtype=np.int64).reshape(-1, 2), gjk_tolerance)
