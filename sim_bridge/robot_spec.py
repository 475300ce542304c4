"""The robot as a ``mujoco.MjSpec``, loaded from the same model file the SPG loads.

:func:`load_robot_spec` turns a :class:`ifc_spg.model.robot_model.RobotModel` into a
:class:`RobotSpec`: the spec (joints not in the reduced model deleted and their bodies
frozen at the locked value), the robot joint names in SPG order, the MuJoCo site of each
chain and the wrist force/torque sensors found in the file. Robot geoms are put in
collision group 2 (``contype=2, conaffinity=1``): they collide with scene geoms but not
with each other (self-collision of mesh models costs ~80 µs/step and the SPG keeps the arm
away from itself anyway).
"""

from dataclasses import dataclass

import mujoco
import numpy as np

from ifc_spg.errors import ModelError, UnknownFrame, did_you_mean
from sim_bridge.models import robot_mjcf_spec

__all__ = ['ROBOT_CONAFFINITY', 'ROBOT_CONTYPE', 'FtSensor', 'RobotSpec', 'load_robot_spec']

ROBOT_CONTYPE = 2
ROBOT_CONAFFINITY = 1


@dataclass(frozen=True)
class FtSensor:
    """A wrist force/torque sensor: a MuJoCo ``force`` + ``torque`` sensor pair on one site.

    Attributes:
        site: Sensor site name (the sensor frame).
        force: Name of the MuJoCo force sensor.
        torque: Name of the MuJoCo torque sensor.
        body: Body carrying the site; the sensor measures what its parent exerts on the
            subtree rooted here (tool weight included).
    """

    site: str
    force: str
    torque: str
    body: str


@dataclass
class RobotSpec:
    """A robot ready to be combined with a scene.

    Attributes:
        spec: The editable MuJoCo spec.
        name: Robot configuration name.
        joint_names: Robot joint names in the order of q.
        chain_sites: Chain id -> MuJoCo site name of the chain frame.
        ft_sensors: Chain id -> :class:`FtSensor` (chains with a wrist sensor only).
        tool_bodies: Chain id -> body whose subtree is "the tool" for contact wrenches.
    """

    spec: mujoco.MjSpec
    name: str
    joint_names: tuple
    chain_sites: dict
    ft_sensors: dict
    tool_bodies: dict


def _body_chain(body):
    """Return ``body`` and its ancestors up to (excluding) the world body."""
    out = []
    while body is not None and body.name != 'world':
        out.append(body)
        body = body.parent
    return out


def _lock_joint(joint, value):
    """Delete-ready: bake ``value`` of a hinge/slide joint into its body's pose."""
    body = joint.parent
    if value == 0.0:
        return
    axis = np.asarray(joint.axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    if joint.type == mujoco.mjtJoint.mjJNT_SLIDE:
        body.pos = np.asarray(body.pos) + _quat_rotate(body.quat, axis * value)
        return
    if joint.type != mujoco.mjtJoint.mjJNT_HINGE:
        raise ModelError(f"cannot lock joint '{joint.name}': only hinge/slide joints")
    q_rot = np.zeros(4)
    mujoco.mju_axisAngle2Quat(q_rot, axis, value)
    # Rotation about the joint anchor a (body frame): T = T_body * Trans(a) R Trans(-a).
    anchor = np.asarray(joint.pos, dtype=float)
    shift = anchor - _quat_rotate(q_rot, anchor)
    body.pos = np.asarray(body.pos) + _quat_rotate(body.quat, shift)
    new_quat = np.zeros(4)
    mujoco.mju_mulQuat(new_quat, np.asarray(body.quat, dtype=float), q_rot)
    body.quat = new_quat


def _quat_rotate(quat, v):
    out = np.zeros(3)
    q = np.asarray(quat, dtype=float)
    mujoco.mju_rotVecQuat(out, np.asarray(v, dtype=float), q / np.linalg.norm(q))
    return out


def load_robot_spec(model):
    """Load ``model.model_file`` into a :class:`RobotSpec` matching the reduced ``model``.

    Args:
        model: A :class:`~ifc_spg.model.robot_model.RobotModel` (its ``model_file``,
            ``joint_names``, ``frames`` and optional ``q_lock`` mapping are used).

    Raises:
        ModelError: The file cannot be loaded or lacks a joint/frame of ``model``.
    """
    spec = robot_mjcf_spec(model)
    joints = {j.name: j for j in spec.joints}
    missing = [j for j in model.joint_names if j not in joints]
    if missing:
        raise ModelError(f"model file '{model.model_file}' lacks joints {missing} of robot "
                         f"'{model.name}'" + did_you_mean(missing[0], joints))
    q_lock = dict(getattr(model, 'q_lock', None) or {})
    for name, joint in list(joints.items()):
        if name in model.joint_names:
            continue
        if joint.type == mujoco.mjtJoint.mjJNT_FREE:
            raise ModelError(f"robot '{model.name}': floating base joint '{name}' is not "
                             'supported; the bridge simulates fixed-base robots')
        _lock_joint(joint, float(q_lock.get(name, 0.0)))
        spec.delete(joint)
    sites = {s.name: s for s in spec.sites}
    bodies = {b.name: b for b in spec.bodies}
    chain_sites = {}
    for chain, frame in model.frames.items():
        if frame in sites:
            chain_sites[chain] = frame
        elif frame in bodies:
            site_name = f'{frame}_frame'
            if site_name not in sites:
                sites[site_name] = bodies[frame].add_site(name=site_name)
            chain_sites[chain] = site_name
        else:
            raise UnknownFrame(f"robot '{model.name}': chain '{chain}' frame '{frame}' is "
                               'neither a site nor a body in the MuJoCo model'
                               + did_you_mean(frame, list(sites) + list(bodies)))
    ft_sensors, tool_bodies = _find_ft_sensors(spec, sites, chain_sites)
    for geom in spec.geoms:
        geom.contype = ROBOT_CONTYPE
        geom.conaffinity = ROBOT_CONAFFINITY
    return RobotSpec(spec=spec, name=model.name, joint_names=tuple(model.joint_names),
                     chain_sites=chain_sites, ft_sensors=ft_sensors, tool_bodies=tool_bodies)


def _has_geoms(body):
    return bool(body.geoms) or any(_has_geoms(child) for child in body.bodies)


def _find_ft_sensors(spec, sites, chain_sites):
    """Match force/torque sensor pairs to the chains whose frame lies below their site."""
    force, torque = {}, {}
    for sensor in spec.sensors:
        if sensor.objtype != mujoco.mjtObj.mjOBJ_SITE:
            continue
        if not sensor.name:
            sensor.name = f'{sensor.objname}_{int(sensor.type)}'
        if sensor.type == mujoco.mjtSensor.mjSENS_FORCE:
            force[sensor.objname] = sensor.name
        elif sensor.type == mujoco.mjtSensor.mjSENS_TORQUE:
            torque[sensor.objname] = sensor.name
    ft_sensors, tool_bodies = {}, {}
    for chain, site_name in chain_sites.items():
        ancestors = _body_chain(sites[site_name].parent)
        # The tool: the first body (from the frame up) whose subtree has geometry.
        tool = next((b for b in ancestors if _has_geoms(b)), ancestors[0])
        tool_bodies[chain] = tool.name
        for body in ancestors:
            found = [s for s in body.sites if s.name in force and s.name in torque]
            if found:
                s = found[0]
                ft_sensors[chain] = FtSensor(site=s.name, force=force[s.name],
                                             torque=torque[s.name], body=body.name)
                tool_bodies[chain] = body.name
                break
    return ft_sensors, tool_bodies
