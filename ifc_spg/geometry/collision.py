"""Collision geometry of a robot model and its obstacles: distances, witness points, rows.

The geometry comes from the same model file pinocchio loads: an MJCF file's primitives
(``pin.buildGeomFromMJCF``: capsules stay capsules, cylinders cylinders), or a URDF file's
collision meshes (``pin.buildGeomFromUrdf``, the iCub's), each replaced by its convex hull
(coal/qhull, built once per process: GJK on a hull costs ~4 us a pair where the triangle
mesh costs ~700 us, and the hull, unlike a fitted primitive, adds no numbers of ours). The
distances come from coal (GJK/EPA, signed: negative when two shapes overlap). Obstacles
(box, sphere, capsule, cylinder, plane) are added to the same ``GeometryModel``, fixed to
the base or to a frame of the robot.

For a pair (a, b) with witness points p_a on a and p_b on b and the unit normal n from a
to b, the distance rate is

    d_dot = n^T (J_b(p_b) - J_a(p_a)) qdot,     J_x(p) = J_lin - [p - o_x]_x J_ang

(J of the parent joint x, LOCAL_WORLD_ALIGNED), one row per pair. A cheap cull runs
first: each shape has a bounding sphere in its joint frame, and a pair whose spheres are
farther apart than the asked influence distance is not passed to coal at all.

Self pairs (:meth:`CollisionGeometry.self_pairs`) are all pairs of the robot's shapes
except those on the same joint (their distance never changes), those on adjacent bodies
(a body and its parent body), and those in contact at the model's reference pose
``robot.q_home`` (:attr:`CollisionGeometry.excluded` lists each with its reason).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
import math
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any, NamedTuple

import coal
import numpy as np
import pinocchio as pin

from ifc_spg.errors import ModelError, ParameterError, did_you_mean
from ifc_spg.geometry import narrowphase
from ifc_spg.kernels import reference as reference_kernels
from ifc_spg.kernels import resolve

if TYPE_CHECKING:
    from ifc_spg.model.robot_model import RobotModel

__all__ = ['OBSTACLE_SHAPES', 'CollisionGeometry', 'Distances', 'Obstacle', 'PairQuery',
           'rpy_matrix']

#: Obstacle shapes and their size fields [m].
OBSTACLE_SHAPES = {
    'box': ('size',),  # full edge lengths (x, y, z)
    'sphere': ('radius',),
    'capsule': ('radius', 'length'),  # length of the axis (z) between the cap centers
    'cylinder': ('radius', 'length'),  # along z
    'plane': (),  # the half-space z <= 0 of its pose; the robot is on the +z side
}
_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_MAX_SIZE = 1e3  # [m]
#: Below this distance [m] the normal is coal's, above it (p_b - p_a) / d.
_NORMAL_FROM_POINTS = 1e-6
#: [m] how much farther from the base an obstacle fixed to a moving frame may be moved at
#: run time than where it is declared (the cull's lever bound includes it)
ATTACHED_ALLOWANCE = 0.25
#: GJK/EPA tolerance of the distance queries [m].
GJK_TOLERANCE = 1e-9


def rpy_matrix(rpy: Sequence[float]) -> np.ndarray:
    """Rotation matrix of roll-pitch-yaw angles [rad] (R = Rz(yaw) Ry(pitch) Rx(roll))."""
    return pin.rpy.rpyToMatrix(*(float(a) for a in rpy))


@dataclass(frozen=True)
class Obstacle:
    """A known obstacle.

    Attributes:
        name: Unique name (used in pairs and reports).
        shape: One of :data:`OBSTACLE_SHAPES`.
        size: The shape's sizes [m]: box (x, y, z) full edge lengths; sphere (radius,);
            capsule and cylinder (radius, length) along the local z axis; plane ().
        frame: 'base' or a chain id of the robot the pose is given in (the obstacle moves
            with that frame).
        position: Position of the shape's center [m] in ``frame``.
        rotation: Orientation (3 x 3, rows) in ``frame``.
    """

    name: str
    shape: str
    size: tuple = ()
    frame: str = 'base'
    position: tuple = (0.0, 0.0, 0.0)
    rotation: tuple = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))

    def __post_init__(self) -> None:
        """Check shape, sizes and pose (ParameterError naming the obstacle and field)."""
        if self.shape not in OBSTACLE_SHAPES:
            raise ParameterError(f"obstacle '{self.name}': unknown shape {self.shape!r}"
                                 f'{did_you_mean(self.shape, OBSTACLE_SHAPES)}; shapes: '
                                 f"{', '.join(OBSTACLE_SHAPES)}")
        want = 3 if self.shape == 'box' else len(OBSTACLE_SHAPES[self.shape])
        size = np.asarray(self.size, dtype=float).reshape(-1)
        if size.size != want or not np.all(np.isfinite(size)) or np.any(size <= 0) \
                or np.any(size > _MAX_SIZE):
            raise ParameterError(f"obstacle '{self.name}': a {self.shape} needs {want} finite "
                                 f'size(s) in (0, {_MAX_SIZE:g}] m '
                                 f"({', '.join(OBSTACLE_SHAPES[self.shape]) or 'none'}), got "
                                 f'{list(self.size)}')
        p = np.asarray(self.position, dtype=float)
        R = np.asarray(self.rotation, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ParameterError(f"obstacle '{self.name}': position must be 3 finite numbers, "
                                 f'got {list(self.position)}')
        if R.shape != (3, 3) or not np.all(np.isfinite(R)) or \
                np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0:
            raise ParameterError(f"obstacle '{self.name}': rotation must be a rotation matrix")

    def geometry(self) -> Any:
        """The coal shape (centered at the obstacle's pose)."""
        s = [float(x) for x in self.size]
        if self.shape == 'box':
            return coal.Box(*s)
        if self.shape == 'sphere':
            return coal.Sphere(s[0])
        if self.shape == 'capsule':
            return coal.Capsule(s[0], s[1])
        if self.shape == 'cylinder':
            return coal.Cylinder(s[0], s[1])
        return coal.Halfspace(np.array([0.0, 0.0, 1.0]), 0.0)

    def placement(self) -> pin.SE3:
        """The pose in :attr:`frame`."""
        return pin.SE3(np.asarray(self.rotation, dtype=float),
                       np.asarray(self.position, dtype=float))


def _bounding_radius(geom: Any) -> float:
    """Radius of a sphere around the shape's origin containing it (inf for a half-space)."""
    if isinstance(geom, coal.Sphere):
        return float(geom.radius)
    if isinstance(geom, coal.Capsule):
        return float(geom.radius + geom.halfLength)
    if isinstance(geom, coal.Cylinder):
        return float(math.hypot(geom.radius, geom.halfLength))
    if isinstance(geom, coal.Box):
        return float(np.linalg.norm(geom.halfSide))
    if isinstance(geom, (coal.Halfspace, coal.Plane)):
        return math.inf
    geom.computeLocalAABB()
    return float(np.linalg.norm(geom.aabb_center) + geom.aabb_radius)


#: (URDF path, the model's frames) -> its collision geometry with convex hulls
_URDF_HULLS: dict[tuple[str, tuple], pin.GeometryModel] = {}


def _urdf_hulls(model: pin.Model, path: str) -> pin.GeometryModel:
    """The collision geometry of a URDF file, each mesh replaced by its convex hull.

    A copy of the process-wide one of (``path``, the model's frames: every model of the same
    robot shares it): loading the meshes and building the hulls takes ~2 s for the iCub,
    once.
    """
    key = (path, tuple((f.name, f.parentJoint, f.parentFrame) for f in model.frames))
    gm = _URDF_HULLS.get(key)
    if gm is None:
        gm = _URDF_HULLS[key] = _build_urdf_hulls(model, path)
    return gm.copy()


def _build_urdf_hulls(model: pin.Model, path: str) -> pin.GeometryModel:
    # ``package://NAME/...`` is looked up in the four folders above the URDF file (the
    # icub-models wheel: share/iCub/robots/<model>/model.urdf, meshes in share/iCub/meshes)
    dirs = [str(p) for p in Path(path).resolve().parents[:4]]
    gm = pin.buildGeomFromUrdf(model, path, pin.GeometryType.COLLISION, package_dirs=dirs)
    for o in gm.geometryObjects:
        mesh = o.geometry
        if isinstance(mesh, coal.BVHModelBase):
            # the hull about the center of the mesh's bounding box, so that the cull's
            # bounding sphere (about the shape's origin) is the box's, not one about the
            # link frame the mesh was drawn in (522 of the 564 iCub self pairs passed the
            # first cull at 5 cm with the latter, 54 with the box's)
            mesh.computeLocalAABB()
            center = np.array(mesh.aabb_center)
            points = coal.StdVec_Vec3s()
            points.extend(list(np.array(mesh.vertices()) - center))
            o.geometry = coal.ConvexBase.convexHull(points, True, 'Qt')  # keep triangles
            o.placement = o.placement * pin.SE3(np.eye(3), center)
    return gm


class CollisionGeometry:
    """The collision shapes of a robot (from its model file) and of its obstacles.

    Args:
        robot: The :class:`~ifc_spg.model.RobotModel` (its ``model_file`` an MJCF file, or a
            URDF file whose collision meshes are taken as their convex hulls).
        obstacles: :class:`Obstacle` objects (unique names, frames 'base' or chain ids).

    Attributes:
        model: The pinocchio ``GeometryModel`` (robot shapes first, then the obstacles).
        robot_geoms: Names of the robot's shapes, in model order.
        bodies: Body (link) name -> indices of its shapes.
        obstacles: Obstacle name -> index of its shape.
        excluded: ``[(shape a, shape b, reason)]`` of the robot pairs left out of
            :meth:`self_pairs`.
    """

    def __init__(self, robot: RobotModel, obstacles: Iterable[Obstacle] = ()) -> None:
        self.robot = robot
        path = robot.model_file
        if path is None or not str(path).lower().endswith(('.xml', '.mjcf', '.urdf')):
            raise ModelError(f"robot '{robot.name}': collision geometry is read from an MJCF "
                             f'or URDF model file; this model was loaded from {path!r}')
        try:
            if str(path).lower().endswith('.urdf'):
                gm = _urdf_hulls(robot.model, str(path))
            else:
                gm = pin.buildGeomFromMJCF(robot.model, str(path), pin.GeometryType.COLLISION)
        except (RuntimeError, ValueError) as exc:
            raise ModelError(f"robot '{robot.name}': cannot read the collision geometry of "
                             f"'{path}': {exc}") from exc
        self.model = gm
        model = robot.model
        self.robot_geoms = tuple(o.name for o in gm.geometryObjects)
        self.bodies: dict[str, list[int]] = {}
        for i, o in enumerate(gm.geometryObjects):
            self.bodies.setdefault(model.frames[o.parentFrame].name, []).append(i)
        self.obstacles: dict[str, int] = {}
        #: name -> the :class:`Obstacle` as declared
        self.declared: dict[str, Obstacle] = {}
        for obs in obstacles:
            self._add_obstacle(obs)
        objs = gm.geometryObjects
        self.parent_joint = np.array([o.parentJoint for o in objs], dtype=int)
        self.center = np.array([o.placement.translation for o in objs], dtype=float)
        self.radius = np.array([_bounding_radius(o.geometry) for o in objs], dtype=float)
        #: ``support[j, k]``: 1.0 where velocity k moves the body of joint j
        self.support = np.zeros((robot.model.njoints, robot.n))
        for j in range(1, robot.model.njoints):
            for s in list(robot.model.supports[j])[1:]:
                self.support[j, robot.model.joints[s].idx_v] = 1.0
        self.lever = self._lever_bound()
        self._self_pairs, self.excluded = self._find_self_pairs()

    def _lever_bound(self) -> float:
        """A bound [m] on the distance of any point of a moving shape from any joint axis.

        Twice the largest reach from the base over the kinematic chain (joint offsets, the
        shape's offset and bounding radius), at any configuration; a joint moved by dq
        moves no point of the shapes by more than ``lever * |dq|`` (prismatic: ``|dq|``,
        and ``lever >= 1``). Capped at 1e6 (a half-space fixed to a link).
        """
        model = self.robot.model
        chain = np.zeros(model.njoints)
        for j in range(1, model.njoints):
            chain[j] = chain[model.parents[j]] + np.linalg.norm(
                model.jointPlacements[j].translation)
        self._chain = chain  # per joint: the reach of its origin from the base, at most
        moving = self.parent_joint > 0
        if not moving.any():
            return 1.0
        reach = chain[self.parent_joint] + np.linalg.norm(self.center, axis=1) + self.radius
        # an obstacle fixed to a moving frame may be moved (spg/obstacles) up to
        # ATTACHED_ALLOWANCE farther out than declared (obstacle_placement checks it)
        for name, obs in self.declared.items():
            if obs.frame != 'base':
                reach[self.obstacles[name]] += ATTACHED_ALLOWANCE
        return float(min(max(2.0 * reach[moving].max(), 1.0), 1e6))

    def _add_obstacle(self, obs: Obstacle) -> None:
        if obs.name in self.obstacles or obs.name in self.bodies:
            raise ParameterError(f"obstacle '{obs.name}': the name is used twice (obstacle and "
                                 'link names must be unique)')
        model = self.robot.model
        if obs.frame == 'base':
            joint, frame, placement = 0, 0, obs.placement()
        else:
            fid = self.robot.frame_id(obs.frame)  # UnknownFrame with the choices
            f = model.frames[fid]
            joint, frame, placement = f.parentJoint, fid, f.placement * obs.placement()
        go = pin.GeometryObject(f'obstacle:{obs.name}', joint, frame, placement,
                                obs.geometry())
        self.obstacles[obs.name] = self.model.addGeometryObject(go)
        self.declared[obs.name] = obs

    def obstacle_placement(self, name: str, pose: Sequence[float] | np.ndarray) -> pin.SE3:
        """Where obstacle ``name`` is in its joint's frame, at ``pose`` in its declared frame.

        Args:
            name: A declared obstacle.
            pose: Position [m] and unit quaternion (x, y, z, w) of its center in the frame
                it was declared in (the base, or a chain id: it moves with that frame).

        Raises:
            ParameterError: The pose puts an obstacle fixed to a moving frame farther from
                its joint than the cull's lever bound (:attr:`lever`) allows (about
                :data:`ATTACHED_ALLOWANCE` beyond where it is declared): the cull would no
                longer bound how far the joints move it (declare it there instead).
        """
        obs = self.declared[name]
        x, y, z, w = (float(v) for v in pose[3:])
        placement = pin.SE3(pin.Quaternion(w, x, y, z).toRotationMatrix(),
                            np.array(pose[:3], dtype=float))
        if obs.frame == 'base':
            return placement
        f = self.robot.model.frames[self.robot.frame_id(obs.frame)]
        placement = f.placement * placement
        shape = self.obstacles[name]
        reach = (self._chain[f.parentJoint] + float(np.linalg.norm(placement.translation))
                 + self.radius[shape])
        if f.parentJoint > 0 and not 2.0 * reach <= self.lever:
            raise ParameterError(
                f"obstacle '{name}' (fixed to frame '{obs.frame}'): a pose "
                f'{float(np.linalg.norm(pose[:3])):.3g} m from the frame puts it {reach:.3g} m '
                f"from the base along the chain, beyond the collision cull's bound "
                f'({self.lever / 2:.3g} m); declare it there in a new stack')
        return placement

    # -- pairs -----------------------------------------------------------------------------
    def _parent_body(self, frame_id: int) -> str | None:
        frames = self.robot.model.frames
        f = frames[frame_id].parentFrame
        while f > 0 and frames[f].type != pin.FrameType.BODY:
            if frames[f].parentFrame == f:
                # pinocchio's buildReducedModel leaves the frame of a locked joint its own
                # parent (the iCub's legs and neck): no parent body known; the shapes of a
                # locked joint share their joint with their parent's, excluded anyway
                return None
            f = frames[f].parentFrame
        return frames[f].name if f > 0 else None

    def _find_self_pairs(self) -> tuple[list[tuple[int, int]], list[tuple[str, str, str]]]:
        objs = self.model.geometryObjects
        frames = self.robot.model.frames
        n_robot = len(self.robot_geoms)
        body = [frames[objs[i].parentFrame].name for i in range(n_robot)]
        parent = [self._parent_body(objs[i].parentFrame) for i in range(n_robot)]
        pairs, excluded, candidates = [], [], []
        for a in range(n_robot):
            for b in range(a + 1, n_robot):
                names = (objs[a].name, objs[b].name)
                if objs[a].parentJoint == objs[b].parentJoint:
                    excluded.append(names + ('same joint (fixed to each other)',))
                elif parent[a] == body[b] or parent[b] == body[a]:
                    excluded.append(names + ('adjacent bodies',))
                else:
                    candidates.append((a, b))
        query = PairQuery(self, candidates)
        data = self.robot.create_data()
        pin.forwardKinematics(self.robot.model, data, np.asarray(self.robot.q_home))
        dist = query.distances_only(data)
        for (a, b), d in zip(candidates, dist):
            if d <= 0.0:
                excluded.append((objs[a].name, objs[b].name,
                                 f'in contact at the reference pose q_home ({d * 1e3:.1f} mm)'))
            else:
                pairs.append((a, b))
        return pairs, excluded

    def self_pairs(self) -> list[tuple[int, int]]:
        """The robot's self-collision pairs (shape indices), see the module doc."""
        return list(self._self_pairs)

    def link_shapes(self, link: str) -> list[int]:
        """Shape indices of a link (MJCF body name) or of one shape by its name."""
        if link in self.bodies:
            return list(self.bodies[link])
        if link in self.robot_geoms:
            return [self.robot_geoms.index(link)]
        raise ParameterError(f"'{link}' is not a link of robot '{self.robot.name}'"
                             f'{did_you_mean(link, list(self.bodies) + list(self.robot_geoms))}'
                             f"; links: {', '.join(self.bodies)}")

    def obstacle_shape(self, name: str) -> int:
        """Shape index of obstacle ``name``."""
        if name not in self.obstacles:
            raise ParameterError(f"'{name}' is not a declared obstacle"
                                 f'{did_you_mean(name, self.obstacles)}; obstacles: '
                                 f"{', '.join(self.obstacles) or '(none declared)'}")
        return self.obstacles[name]

    def shape_name(self, i: int) -> str:
        """Name of shape ``i`` (obstacles as ``obstacle:NAME``)."""
        return self.model.geometryObjects[i].name


class Distances(NamedTuple):
    """Distances of a pair set at one configuration.

    Attributes:
        distance: Signed distance per pair [m] (negative: overlap); for culled pairs a
            lower bound (the bounding spheres' gap), see ``exact``.
        exact: True where coal computed the distance (the pair was not culled).
        rows: d(distance)/dq per pair (m, n); zero rows for culled pairs.
        point_a, point_b: Witness points (m, 3) in the base frame (NaN for culled pairs
            and pairs beyond the influence distance).
    """

    distance: np.ndarray
    exact: np.ndarray
    rows: np.ndarray
    point_a: np.ndarray
    point_b: np.ndarray


class PairQuery:
    """Distances and distance Jacobian rows of a fixed list of shape pairs.

    Owns its narrowphase (:mod:`ifc_spg.geometry.narrowphase`: the C++ module on coal, or
    pinocchio's Python bindings) and a pinocchio ``GeometryModel``/``GeometryData`` of its
    pairs (:meth:`distances_only`); one query per task and thread.

    Args:
        geometry: The :class:`CollisionGeometry`.
        pairs: ``[(a, b)]`` shape indices.
        kernels: :mod:`ifc_spg.kernels` module of the rows (default: the active one).
    """

    def __init__(self, geometry: CollisionGeometry, pairs: Sequence[tuple[int, int]],
                 kernels: ModuleType | None = None) -> None:
        self.geometry = geometry
        #: the :mod:`ifc_spg.kernels` module of the cull and the rows
        self.kernels = resolve(kernels)
        #: the pairs of the last :meth:`compute` within the influence distance (ascending)
        self.within = np.zeros(0, dtype=np.intp)
        self.pairs = [(int(a), int(b)) for a, b in pairs]
        self.m = len(self.pairs)
        robot_model = geometry.robot.model
        # pinocchio's own query of the pairs: distances_only, and the narrowphase where the
        # C++ module is not used
        self._pin = narrowphase.PinocchioPairs(geometry.model, robot_model, self.pairs,
                                               geometry.radius, GJK_TOLERANCE)
        self._gm = self._pin.model
        self._narrow = narrowphase.pairs(self._gm, robot_model, self.pairs, geometry.radius,
                                         GJK_TOLERANCE) \
            if narrowphase.native is not None else self._pin
        self._n = geometry.robot.n
        # the C++ module's level(): the steps of level() in one call, with the C kernels'
        # arithmetic (collision_core.h); not with the reference (numpy) kernels
        self._fused = getattr(self._narrow, 'level', None) \
            if self._narrow is not self._pin and self.kernels is not reference_kernels else None
        ia = np.array([a for a, _ in self.pairs], dtype=int)
        ib = np.array([b for _, b in self.pairs], dtype=int)
        self._ia, self._ib = ia, ib
        support = geometry.support
        self._mask_a = support[geometry.parent_joint[ia]]
        self._mask_b = support[geometry.parent_joint[ib]]
        # joints that move one shape of a pair but not the other, times the lever bound
        self._lever = np.abs(self._mask_a - self._mask_b) * geometry.lever
        self._last_q: np.ndarray | None = None  # (a buffer, once there is a last call)
        self._last_bound = np.zeros(self.m)  # never written in place: compute's distance
        self._data: pin.Data | None = None  # the Data of the last call and its data.J (a
        self._J = np.zeros((6, self._n))  # view, written in place by pinocchio)
        self._normal = np.zeros((self.m, 3))  # scratch: the unit normals of the pairs within
        self._no_points = np.full((self.m, 3), np.nan)  # the witness points of no pair
        self._no_points.setflags(write=False)

    def move_shape(self, shape: int, placement: pin.SE3) -> None:
        """Place shape ``shape`` (an obstacle) at ``placement`` in its joint's frame from now on.

        In this query only (it owns a copy of the geometry). The distances kept for the cull
        across calls (``compute(..., q=...)``) of the pairs with that shape are dropped: the
        shape moved by an unknown amount, so the last distance minus the joints' motion is
        no lower bound any more; the next call computes those pairs with coal.
        """
        rotation, translation = placement.rotation, placement.translation
        self._pin.move_shape(shape, rotation, translation)
        if self._narrow is not self._pin:
            self._narrow.move_shape(shape, rotation, translation)
        bound = self._last_bound.copy()  # (the last call's distances, returned to its caller)
        bound[(self._ia == shape) | (self._ib == shape)] = -np.inf
        self._last_bound = bound

    # -- the cull --------------------------------------------------------------------------
    def lower_bounds(self, data: pin.Data) -> np.ndarray:
        """Lower bounds on each pair's distance from the bounding spheres (cheap).

        ``data`` holds the joint placements (``forwardKinematics``) of the configuration.
        """
        gap = np.empty(self.m)
        self._narrow.gaps(data, gap)
        return gap

    # -- exact distances -------------------------------------------------------------------
    def distances_only(self, data: pin.Data) -> np.ndarray:
        """Exact signed distances of every pair (no cull, no rows); ``data`` has oMi.

        pinocchio's Python bindings, whichever narrowphase :meth:`compute` uses.
        """
        out = np.empty(self.m)
        self._pin.distances(data, out)
        return out

    def compute(self, data: pin.Data, influence: float = math.inf,
                jacobians: bool = True, q: np.ndarray | None = None) -> Distances:
        """Distances, witness points and rows at the configuration of ``data``.

        Args:
            data: pinocchio ``Data`` after ``computeJointJacobians`` (or
                ``forwardKinematics`` when ``jacobians`` is False) at the configuration.
            influence: Pairs whose bounding spheres are farther apart than this [m] are
                culled (their distance is a lower bound, their row zero); pairs farther
                than this get their exact distance but no witness points (NaN) and a zero
                row.
            jacobians: Compute the rows (``data`` must hold the joint Jacobians).
            q: The configuration of ``data``, for the cull across calls (a sequence of
                configurations, one query per sequence): a pair's distance changes by at
                most ``sum_k lever |q_k - q_prev,k|`` over the joints k that move one of
                its shapes but not the other, so the last call's distances (exact or
                bounds) minus that stay lower bounds, and the bounding spheres are not
                needed. None: the bounding-sphere cull only, nothing kept.
        """
        m, n = self.m, self._n
        near = None
        if not math.isfinite(influence):
            dist = np.full(m, -np.inf)
        elif q is not None and self._last_q is not None:
            dist = np.empty(m)
            near = self.kernels.collision_cull(self._last_bound, self._lever, q,
                                                self._last_q, influence, dist)
        else:
            dist = np.empty(m)
            self._narrow.gaps(data, dist)
        if near is None:
            near = (dist <= influence).nonzero()[0]
        exact = np.zeros(m, dtype=bool)
        rows = np.zeros((m, n))
        pa = self._no_points.copy()  # (copies of a NaN array: ~3 us less per tick than
        pb = self._no_points.copy()  # np.empty + fill in the closed loop)
        if near.size:
            # coal's distances of the pairs near; witness points (and coal's normal where
            # touching) of those within. The rows are n^T (J_b(p_b) - J_a(p_a)) (the kernel
            # collision_rows): with the joint Jacobians in the world frame (data.J, spatial
            # velocity at the origin), the velocity of a point p of joint j's body is the
            # columns of j's support of v + w x p, so n^T J(p) = (n^T J_v + (p x n)^T J_w) on
            # those columns.
            within = self._narrow.narrowphase(data, near, influence, _NORMAL_FROM_POINTS,
                                              dist, pa, pb, self._normal)
            if within.size and jacobians:
                if data is not self._data:
                    self._data, self._J = data, data.J
                self.kernels.collision_rows(self._J, within, None, pa, pb, dist, self._normal,
                                            self._mask_a, self._mask_b, _NORMAL_FROM_POINTS,
                                            rows)
            exact[near] = True
            self.within = within
        else:
            self.within = np.zeros(0, dtype=np.intp)
        if q is not None:
            if self._last_q is None:
                self._last_q = np.empty(n)
            self._last_q[:] = q
            self._last_bound = dist
        return Distances(dist, exact, rows, pa, pb)

    def level(self, data: pin.Data, influence: float, q: np.ndarray, gain: float, margin: float,
              R: int) -> tuple[Distances, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`compute` (``q`` given) and the velocity damper rows of its pairs.

        The rows of :class:`~ifc_spg.tasks.CollisionAvoidanceTask`: of the pairs within
        (:attr:`within`) those closer than ``influence``, ascending; the first ``R`` fill
        ``A[t]`` with their row and ``lower[t] = -gain (d - margin)``, the other rows of
        ``A`` (R, n) are zero with ``lower`` -inf (the kernel ``collision_level``).

        Returns:
            The :class:`Distances`, the pairs closer than ``influence`` (all of them, also
            those beyond the first R), ``A`` and ``lower`` (new arrays).
        """
        if self._fused is None or self._last_q is None or not math.isfinite(influence):
            A, lower = np.empty((R, self._n)), np.empty(R)
            res = self.compute(data, influence, q=q)
            return res, self.kernels.collision_level(res.rows, res.distance, self.within,
                                                     influence, gain, margin, A, lower), A, lower
        if data is not self._data:
            self._data, self._J = data, data.J
        dist, exact, rows, pa, pb, self.within, pairs, A, lower = self._fused(
            data, self._J, q, influence, _NORMAL_FROM_POINTS, gain, margin, R,
            self._last_bound, self._lever, self._last_q, self._mask_a, self._mask_b,
            self._normal)
        self._last_bound = dist
        return Distances(dist, exact, rows, pa, pb), pairs, A, lower
