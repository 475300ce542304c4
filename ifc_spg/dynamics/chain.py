"""A serial kinematic chain taken from a pinocchio model, in the arrays the sweeps need.

The Popov-Vereshchagin sweeps run on a chain of 1-DoF joints (revolute or prismatic),
each followed by one rigid segment. Fixed joints are folded into the segment they are
attached to: pinocchio's URDF/MJCF parsers already merge the inertia of links behind
fixed joints into the supporting body and keep those links as operational frames, so a
tool frame behind a fixed joint is a frame of the last segment here.

Conventions (the same as pinocchio): segment i's frame is the frame of joint i; its
spatial inertia ``model.inertias[i]`` is expressed there; rotor inertias d_j come from
``model.armature``; spatial vectors are ordered [linear; angular].
"""

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ifc_spg.errors import ModelError, UnknownFrame, did_you_mean

__all__ = ['Chain', 'chain_from_model']

_REVOLUTE = {'JointModelRX': (1.0, 0.0, 0.0), 'JointModelRY': (0.0, 1.0, 0.0),
             'JointModelRZ': (0.0, 0.0, 1.0), 'JointModelRevoluteUnaligned': None}
_UNBOUNDED = {'JointModelRUBX': (1.0, 0.0, 0.0), 'JointModelRUBY': (0.0, 1.0, 0.0),
              'JointModelRUBZ': (0.0, 0.0, 1.0), 'JointModelRevoluteUnboundedUnaligned': None}
_PRISMATIC = {'JointModelPX': (1.0, 0.0, 0.0), 'JointModelPY': (0.0, 1.0, 0.0),
              'JointModelPZ': (0.0, 0.0, 1.0), 'JointModelPrismaticUnaligned': None}


def _readonly(a, dtype=float):
    a = np.ascontiguousarray(a, dtype=dtype)
    a.setflags(write=False)
    return a


def _skew(v):
    x, y, z = v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


@dataclass(frozen=True)
class Chain:
    """Constant data of a serial chain (read-only arrays, n joints).

    Attributes:
        model: The pinocchio model the chain was taken from (not modified).
        n: Number of joints (= model.nv).
        joint_names: Joint names in chain order.
        revolute: (n,) True for revolute, False for prismatic joints.
        axis: (n, 3) joint axis in the joint frame (unit vector).
        axis_skew: (n, 3, 3) skew matrices of ``axis`` (Rodrigues' formula).
        axis_skew2: (n, 3, 3) squares of ``axis_skew``.
        R_parent: (n, 3, 3) rotation of joint frame i (at q_i = 0) in the frame of joint i-1.
        p_parent: (n, 3) origin of joint frame i in the frame of joint i-1 in [m].
        mass: (n,) segment masses in [kg].
        com: (n, 3) segment centre of mass in the joint frame in [m].
        inertia_com: (n, 3, 3) rotational inertia about the COM, joint-frame axes [kg m^2].
        armature: (n,) rotor inertias d_j in [kg m^2] (revolute) or [kg] (prismatic).
        idx_q: (n,) index of each joint's first entry in pinocchio's q.
        unbounded: (n,) True for continuous joints stored as (cos, sin) in q.
        tip_frame: Name of the frame on the last segment where A_N acts.
        tip_placement: (4, 4) pose of the tip frame in the last joint frame.
    """

    model: pin.Model
    n: int
    joint_names: tuple[str, ...]
    revolute: np.ndarray
    axis: np.ndarray
    axis_skew: np.ndarray
    axis_skew2: np.ndarray
    R_parent: np.ndarray
    p_parent: np.ndarray
    mass: np.ndarray
    com: np.ndarray
    inertia_com: np.ndarray
    armature: np.ndarray
    idx_q: np.ndarray
    unbounded: np.ndarray
    tip_frame: str
    tip_placement: np.ndarray

    def joint_angles(self, q):
        """Return the (n,) joint coordinates from pinocchio's configuration vector ``q``.

        Continuous joints (nq = 2, stored as cos, sin) are turned into angles in [rad].
        """
        q = np.asarray(q, dtype=float)
        if q.shape != (self.model.nq,):
            raise ModelError(f'q must have shape ({self.model.nq},) (pinocchio nq of this '
                             f'chain), got {q.shape}')
        out = q[self.idx_q]
        if self.unbounded.any():
            out = out.copy()
            ub = np.flatnonzero(self.unbounded)
            out[ub] = np.arctan2(q[self.idx_q[ub] + 1], q[self.idx_q[ub]])
        return out


def chain_from_model(model, tip_frame=None):
    """Build a :class:`Chain` from a pinocchio model of a fixed-base serial chain.

    Args:
        model: pinocchio ``Model`` (or an object with a ``.model`` attribute, e.g.
            :class:`ifc_spg.RobotModel`) whose joints form one serial chain of revolute,
            continuous or prismatic joints.
        tip_frame: Name of a frame attached to the last joint's segment where the
            constraint forces A_N act; default: the last joint's own frame.

    Raises:
        ModelError: The model branches, has a joint type other than 1-DoF revolute /
            prismatic, or has no joints.
        UnknownFrame: ``tip_frame`` is not a frame of the model or not on the last segment.
    """
    model = getattr(model, 'model', model)
    if not isinstance(model, pin.Model):
        raise ModelError(f'expected a pinocchio Model or RobotModel, got {type(model).__name__}')
    n = model.njoints - 1
    if n < 1:
        raise ModelError('the model has no joints; the solver needs at least one '
                         'revolute or prismatic joint')
    names = tuple(model.names[1:])
    for i in range(1, model.njoints):
        if model.parents[i] != i - 1:
            raise ModelError(
                f"joint '{model.names[i]}' has parent '{model.names[model.parents[i]]}', "
                'so the model is a tree, not a serial chain; reduce it to one chain with '
                'pinocchio.buildReducedModel (lock the joints of the other branches)')
    revolute = np.zeros(n, dtype=bool)
    unbounded = np.zeros(n, dtype=bool)
    axis = np.zeros((n, 3))
    for i in range(n):
        revolute[i], unbounded[i], axis[i] = _joint_axis(model.joints[i + 1], names[i])
    R_parent = np.array([model.jointPlacements[i].rotation for i in range(1, n + 1)])
    p_parent = np.array([model.jointPlacements[i].translation for i in range(1, n + 1)])
    mass = np.array([model.inertias[i].mass for i in range(1, n + 1)])
    com = np.array([model.inertias[i].lever for i in range(1, n + 1)])
    inertia_com = np.array([model.inertias[i].inertia for i in range(1, n + 1)])
    armature = np.array(model.armature, dtype=float).reshape(-1)
    if armature.shape != (n,):
        armature = np.zeros(n)
    idx_q = np.array([model.joints[i].idx_q for i in range(1, n + 1)], dtype=int)
    if tip_frame is None:
        tip_frame = names[-1]
        tip = np.eye(4)
    else:
        tip = _tip_placement(model, tip_frame)
    skew = np.array([_skew(a) for a in axis])
    return Chain(model=model, n=n, joint_names=names, revolute=_readonly(revolute, bool),
                 axis=_readonly(axis), axis_skew=_readonly(skew),
                 axis_skew2=_readonly(skew @ skew), R_parent=_readonly(R_parent),
                 p_parent=_readonly(p_parent), mass=_readonly(mass), com=_readonly(com),
                 inertia_com=_readonly(inertia_com), armature=_readonly(armature),
                 idx_q=_readonly(idx_q, int), unbounded=_readonly(unbounded, bool),
                 tip_frame=str(tip_frame), tip_placement=_readonly(tip))


def _joint_axis(jm, name):
    """``(revolute, unbounded, unit axis (3,))`` of a 1-DoF pinocchio joint model.

    Raises:
        ModelError: Another joint type, or a zero axis.
    """
    kind = jm.shortname()
    for table, is_rev, is_ub in ((_REVOLUTE, True, False), (_UNBOUNDED, True, True),
                                 (_PRISMATIC, False, False)):
        if kind in table:
            fixed_axis = table[kind]
            ax = np.array(fixed_axis) if fixed_axis is not None else np.array(
                jm.extract().axis, dtype=float)
            norm = np.linalg.norm(ax)
            if not norm > 0:
                raise ModelError(f"joint '{name}' has a zero axis")
            return is_rev, is_ub, ax / norm
    raise ModelError(
        f"joint '{name}' is a {kind}; the Popov-Vereshchagin solver supports "
        'revolute, continuous and prismatic joints only (fixed joints are folded by '
        'the URDF/MJCF parser); lock it with pinocchio.buildReducedModel')


def _tip_placement(model, tip_frame):
    """The placement (4, 4) of ``tip_frame`` in the last joint's frame.

    Raises:
        UnknownFrame: No such frame, or it is not on the last segment.
    """
    n = model.njoints - 1
    if not model.existFrame(tip_frame):
        raise UnknownFrame(f"tip frame '{tip_frame}' not in the model"
                           + did_you_mean(tip_frame, [f.name for f in model.frames])
                           + '; it must be a frame on the last segment')
    frame = model.frames[model.getFrameId(tip_frame)]
    if frame.parentJoint != n:
        raise UnknownFrame(
            f"tip frame '{tip_frame}' is attached to joint "
            f"'{model.names[frame.parentJoint]}', not to the last joint "
            f"'{model.names[n]}'; A_N acts on the last segment, so pick a frame of that "
            'segment')
    return frame.placement.homogeneous
