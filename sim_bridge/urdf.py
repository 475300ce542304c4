"""A URDF of a robot, generated from the MJCF both pinocchio and MuJoCo load (Foxglove, RViz).

:func:`urdf_from_robot` compiles the robot's MuJoCo model
(:func:`~sim_bridge.models.robot_mjcf_spec`) and writes its body tree as URDF: a link per
body (its inertial: mass, centre of mass and principal inertia), a ``revolute`` /
``prismatic`` joint per hinge/slide joint (limits from the :class:`RobotModel`), ``fixed``
joints for welded bodies, and a link with a fixed joint per site, so the chain frames
(``tool``, ``flange``, ...) are URDF links of the same name. The root link is MuJoCo's world
body (``world``). Visuals are MuJoCo's primitives: a capsule becomes a cylinder and two
spheres, a mesh its bounding box (URDF needs mesh files a viewer can fetch; the primitives
need none).

:class:`UrdfTree` is the generated tree as data (joints with their origins), from which
:mod:`ifc_spg.offline.foxglove` computes ``tf`` transforms; pinocchio's FK of the URDF text
gives the same frames (test/test_foxglove.py).
"""

from __future__ import annotations

import dataclasses
from xml.sax.saxutils import quoteattr

import mujoco
import numpy as np
import pinocchio as pin

from ifc_spg.errors import ModelError
from sim_bridge.models import robot_mjcf_spec

__all__ = ['UrdfJoint', 'UrdfTree', 'urdf_from_robot']


@dataclasses.dataclass(frozen=True)
class UrdfJoint:
    """One URDF joint: ``parent`` -> ``child`` link at ``origin`` (then ``axis`` motion).

    Attributes:
        name: Joint name (the robot's joint name for moving joints).
        kind: ``'revolute'``, ``'prismatic'`` or ``'fixed'``.
        parent, child: Link names.
        origin: The child frame in the parent frame at q = 0 (pinocchio ``SE3``).
        axis: Unit axis in the joint frame (moving joints).
    """

    name: str
    kind: str
    parent: str
    child: str
    origin: pin.SE3
    axis: np.ndarray

    def transform(self, q=0.0):
        """The child link frame in the parent link frame at joint position ``q``."""
        if self.kind == 'revolute':
            return self.origin * pin.SE3(pin.exp3(self.axis * float(q)), np.zeros(3))
        if self.kind == 'prismatic':
            return self.origin * pin.SE3(np.eye(3), self.axis * float(q))
        return self.origin


@dataclasses.dataclass(frozen=True)
class UrdfTree:
    """The generated URDF and its tree.

    Attributes:
        xml: The URDF document.
        root: Root link name.
        joints: Every joint, parents before children.
    """

    xml: str
    root: str
    joints: tuple

    @property
    def moving(self):
        """The revolute and prismatic joints."""
        return tuple(j for j in self.joints if j.kind != 'fixed')

    @property
    def fixed(self):
        """The fixed joints."""
        return tuple(j for j in self.joints if j.kind == 'fixed')


def _se3(pos, quat_wxyz):
    w, x, y, z = (float(v) for v in quat_wxyz)
    return pin.SE3(pin.Quaternion(w, x, y, z).normalized().toRotationMatrix(),
                   np.asarray(pos, dtype=float).copy())


def _origin(T):
    return (f'<origin xyz="{_num(*T.translation)}" '
            f'rpy="{_num(*pin.rpy.matrixToRpy(T.rotation))}"/>')


def _num(*values):
    return ' '.join(f'{float(v):.12g}' for v in values)


def _shapes(kind, size, T, aabb):
    """``[(pose, URDF geometry)]`` of one MuJoCo geom (type name ``kind``) at pose ``T``."""
    r = size[0]
    if kind == 'SPHERE':
        return [(T, f'<sphere radius="{_num(r)}"/>')]
    if kind == 'BOX':
        return [(T, f'<box size="{_num(*(2 * size))}"/>')]
    if kind in ('CYLINDER', 'CAPSULE'):
        out = [(T, f'<cylinder radius="{_num(r)}" length="{_num(2 * size[1])}"/>')]
        if kind == 'CAPSULE':  # URDF has no capsule: a cylinder and two spheres
            out += [(T * pin.SE3(np.eye(3), np.array([0.0, 0.0, sign * size[1]])),
                     f'<sphere radius="{_num(r)}"/>') for sign in (1.0, -1.0)]
        return out
    if kind == 'ELLIPSOID':
        return [(T, f'<sphere radius="{_num(np.max(size))}"/>')]
    if kind == 'MESH':  # its bounding box in the geom frame
        box = T * pin.SE3(np.eye(3), np.asarray(aabb[:3], float))
        return [(box, f'<box size="{_num(*(2 * np.asarray(aabb[3:], float)))}"/>')]
    return []  # planes, height fields: not part of a robot


def _visuals(mj, body, shift):
    """URDF ``<visual>`` elements of a body's geoms (MuJoCo primitives) in its link frame.

    ``shift`` is the body frame in the link frame.
    """
    out = []
    for g in np.flatnonzero(mj.geom_bodyid == body):
        T = shift * _se3(mj.geom_pos[g], mj.geom_quat[g])
        rgba = mj.geom_rgba[g] if mj.geom_matid[g] < 0 else mj.mat_rgba[mj.geom_matid[g]]
        name = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_GEOM, g) or f'geom{g}'
        kind = mujoco.mjtGeom(int(mj.geom_type[g])).name.removeprefix('mjGEOM_')
        for i, (Ts, geometry) in enumerate(_shapes(kind, mj.geom_size[g], T, mj.geom_aabb[g])):
            out.append(f'    <visual name={quoteattr(f"{name}_{i}" if i else name)}>'
                       f'{_origin(Ts)}<geometry>{geometry}</geometry><material name="">'
                       f'<color rgba="{_num(*rgba)}"/></material></visual>')
    return out


def _joints(mj, robot):
    """The :class:`UrdfJoint` of every body and site, and each body's link offset.

    A link frame sits at its joint (URDF turns a child about its frame's origin), so a body
    whose joint is not at its origin gets a link frame shifted by ``jnt_pos``.
    """
    obj = mujoco.mjtObj
    body_name = [mujoco.mj_id2name(mj, obj.mjOBJ_BODY, b) or f'body{b}' for b in range(mj.nbody)]
    link_offset = [np.zeros(3) for _ in range(mj.nbody)]
    kinds = {int(mujoco.mjtJoint.mjJNT_HINGE): 'revolute',
             int(mujoco.mjtJoint.mjJNT_SLIDE): 'prismatic'}
    joints = []
    for b in range(1, mj.nbody):
        kind, name, axis = 'fixed', f'{body_name[b]}_fixed', np.zeros(3)
        if int(mj.body_jntnum[b]) > 1:
            raise ModelError(f"robot '{robot.name}': body '{body_name[b]}' has "
                             f'{int(mj.body_jntnum[b])} joints; the URDF export needs one '
                             'joint per body')
        if int(mj.body_jntnum[b]) == 1:
            j = int(mj.body_jntadr[b])
            joint_kind = kinds.get(int(mj.jnt_type[j]))
            if joint_kind is None:
                raise ModelError(f"robot '{robot.name}': the joint of body '{body_name[b]}' is "
                                 'not a hinge or slide joint; URDF export writes revolute and '
                                 'prismatic joints only')
            kind = joint_kind
            name = mujoco.mj_id2name(mj, obj.mjOBJ_JOINT, j)
            axis = np.asarray(mj.jnt_axis[j], float).copy()
            link_offset[b] = np.asarray(mj.jnt_pos[j], float).copy()
        parent = int(mj.body_parentid[b])
        origin = pin.SE3(np.eye(3), -link_offset[parent]) * \
            _se3(mj.body_pos[b], mj.body_quat[b]) * pin.SE3(np.eye(3), link_offset[b])
        joints.append(UrdfJoint(name, kind, body_name[parent], body_name[b], origin, axis))
    for s in range(mj.nsite):
        b = int(mj.site_bodyid[s])
        name = mujoco.mj_id2name(mj, obj.mjOBJ_SITE, s)
        origin = pin.SE3(np.eye(3), -link_offset[b]) * _se3(mj.site_pos[s], mj.site_quat[s])
        if name in body_name:  # a site marking a body's frame (iCub l_hand): that link
            if origin.isIdentity(1e-12):
                continue
            name = f'{name}_site'
        joints.append(UrdfJoint(f'{name}_fixed', 'fixed', body_name[b], name, origin,
                                np.zeros(3)))
    return body_name, link_offset, joints


def _limit(robot, mj, joint):
    i = {name: k for k, name in enumerate(robot.joint_names)}.get(joint.name)
    if i is not None:
        return (f'    <limit lower="{_num(robot.q_min[i])}" upper="{_num(robot.q_max[i])}" '
                f'effort="{_num(robot.tau_max[i])}" velocity="{_num(robot.v_max[i])}"/>')
    lo, hi = mj.jnt_range[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, joint.name)]
    return f'    <limit lower="{_num(lo)}" upper="{_num(hi)}" effort="0" velocity="0"/>'


def urdf_from_robot(robot):
    """The robot's URDF, generated from its compiled MJCF (see the module docstring).

    Args:
        robot: A :class:`~ifc_spg.model.RobotModel` MuJoCo can load
            (:func:`~sim_bridge.models.robot_mjcf_spec`).

    Returns:
        :class:`UrdfTree`.

    Raises:
        ModelError: A joint MuJoCo has that URDF cannot express as one joint (ball, free).
    """
    mj = robot_mjcf_spec(robot).compile()
    body_name, link_offset, joints = _joints(mj, robot)
    lines = [f'<?xml version="1.0"?>\n<robot name={quoteattr(robot.name)}>']
    for b in range(mj.nbody):
        lines.append(f'  <link name={quoteattr(body_name[b])}>')
        shift = pin.SE3(np.eye(3), -link_offset[b])
        if b > 0 and mj.body_mass[b] > 0:
            inertia = mj.body_inertia[b]
            com = shift * _se3(mj.body_ipos[b], mj.body_iquat[b])
            lines.append(f'    <inertial>{_origin(com)}'
                         f'<mass value="{_num(mj.body_mass[b])}"/><inertia '
                         f'ixx="{_num(inertia[0])}" ixy="0" ixz="0" iyy="{_num(inertia[1])}" '
                         f'iyz="0" izz="{_num(inertia[2])}"/></inertial>')
        if b > 0:
            lines.extend(_visuals(mj, b, shift))
        lines.append('  </link>')
    for j in joints[mj.nbody - 1:]:  # the sites' links
        lines.append(f'  <link name={quoteattr(j.child)}/>')
    for j in joints:
        lines.append(f'  <joint name={quoteattr(j.name)} type="{j.kind}">'
                     f'<parent link={quoteattr(j.parent)}/><child link={quoteattr(j.child)}/>'
                     f'{_origin(j.origin)}')
        if j.kind != 'fixed':
            lines.append(f'    <axis xyz="{_num(*j.axis)}"/>')
            lines.append(_limit(robot, mj, j))
        lines.append('  </joint>')
    lines.append('</robot>\n')
    return UrdfTree('\n'.join(lines), body_name[0], tuple(joints))
