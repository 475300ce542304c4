"""The named robots as MuJoCo models: ``mujoco.MjSpec`` builders and joint addresses.

The robot tables and model files are in :mod:`ifc_spg.model.registry` (data, no MuJoCo);
this module loads them into MuJoCo for the simulator (and for whoever compiles a robot:
the URDF export, the collision tests):

- :func:`mjcf_spec` builds the spec of a named configuration, :func:`robot_mjcf_spec` the
  spec of any :class:`~ifc_spg.model.RobotModel` (its ``spec_builder``, the named
  configuration it came from, else its ``model_file`` as is);
- :func:`icub_mjcf_spec` reduces the iCub URDF the way the registry reduces it for pinocchio;
- :func:`mujoco_indices` maps a pinocchio configuration into a compiled ``MjModel``.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from ifc_spg.errors import ModelError, UnknownJoint, did_you_mean
from ifc_spg.model import registry
from ifc_spg.model.registry import ICUB_FRAMES, ICUB_JOINTS, ICUB_WIPE_PAD, icub_urdf_path

if TYPE_CHECKING:
    from ifc_spg.model.robot_model import RobotModel

__all__ = ['icub_mjcf_spec', 'mjcf_spec', 'mujoco_indices', 'robot_mjcf_spec']

_ICUB = 'icub_upper_body'


def _icub_mesh_dir(urdf: str) -> str:
    # <share>/iCub/robots/<model>/model.urdf -> <share>/iCub/meshes/simmechanics
    return os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(urdf))), 'meshes',
                        'simmechanics')


def icub_mjcf_spec() -> Any:
    """Return a ``mujoco.MjSpec`` of the iCub upper body from the same URDF as the SPG.

    The URDF gets a ``<mujoco><compiler .../></mujoco>`` block (meshes from the wheel,
    static links kept as bodies), every joint not in
    :data:`~ifc_spg.model.registry.ICUB_JOINTS` is deleted (its child welded at q = 0,
    exactly like pinocchio's reduction) and the added frames
    (:data:`~ifc_spg.model.registry.ICUB_FRAMES`) and the ``l_hand``/``r_hand`` link frames
    become sites, so every chain of ``RobotModel.from_config('icub_upper_body')`` is a site
    of the same name. The left forearm carries a massless wiping pad
    (:data:`~ifc_spg.model.registry.ICUB_WIPE_PAD`, geom ``l_wipe_pad``). The root link is
    fixed to the world at the origin (iCub convention: x backwards, z up). MuJoCo orders the
    joints differently from pinocchio (right arm first): map them by name, see
    :func:`mujoco_indices`.
    """
    urdf = icub_urdf_path()
    with open(urdf, encoding='utf-8') as f:
        text = f.read()
    block = (f'<mujoco><compiler strippath="true" meshdir="{_icub_mesh_dir(urdf)}" '
             'fusestatic="false" discardvisual="true" balanceinertia="false"/></mujoco>')
    start = text.find('<robot')
    end = text.find('>', start)
    if start < 0 or end < 0:
        raise ModelError(f"'{urdf}' is not a URDF file (no <robot> element)")
    text = text[:end + 1] + block + text[end + 1:]
    spec = mujoco.MjSpec.from_string(text)
    for joint in list(spec.joints):
        if joint.name not in ICUB_JOINTS:
            spec.delete(joint)
    for fname, (link, offset) in ICUB_FRAMES.items():
        spec.body(link).add_site(name=fname, pos=list(offset), size=[0.005, 0, 0])
    for side in 'lr':
        spec.body(f'{side}_hand').add_site(name=f'{side}_hand', size=[0.005, 0, 0])
    body, centre, radius = ICUB_WIPE_PAD
    spec.body(body).add_geom(name='l_wipe_pad', type=mujoco.mjtGeom.mjGEOM_SPHERE,
                             size=[radius, 0.0, 0.0], pos=list(centre), mass=0.0)
    for geom in spec.geoms:
        geom.contype, geom.conaffinity = 1, 0  # no self-collision, collide with the scene
    return spec


def mjcf_spec(name: str) -> Any:
    """Return a ``mujoco.MjSpec`` of robot ``name``, loaded from its shared model file.

    The spec has no actuators (apply joint torques with ``qfrc_applied`` or add motors);
    robot geoms have ``contype=1, conaffinity=0``: no self-collision, contacts with every
    scene geom of default ``conaffinity``. Every chain of a named configuration (``tool``,
    ``flange``, ``l_ft``, ``l_contact``, ...) is a site of the same name. Keep the robot's
    root body at the world origin: pinocchio places the robot base at its origin (and
    ignores the pose of the MJCF root body), so a moved robot must be attached to the scene
    through a frame whose pose the SPG side knows.

    Args:
        name: One of :data:`~ifc_spg.model.registry.ROBOTS`.

    Raises:
        UnknownRobot: ``name`` is not a known configuration.
    """
    path = registry.model_file(name)  # checks the name
    if name == _ICUB:
        return icub_mjcf_spec()
    return mujoco.MjSpec.from_file(path)


def robot_mjcf_spec(robot: RobotModel) -> Any:
    """Return a fresh ``mujoco.MjSpec`` of ``robot`` for the simulator.

    The robot's ``spec_builder`` if it has one; a named configuration
    (``RobotModel.from_config``) is built by :func:`mjcf_spec` from the same file pinocchio
    loaded (the iCub: its URDF with MuJoCo compiler options, reduced to the same joints);
    otherwise ``model_file`` is loaded as is.

    Raises:
        ModelError: ``robot`` has no ``model_file``, or MuJoCo cannot load it.
    """
    builder = getattr(robot, 'spec_builder', None)
    if builder is not None:
        return builder()
    if robot.model_file is None:
        raise ModelError(f"model '{robot.name}' has no model_file to load into MuJoCo")
    if robot.name == _ICUB and robot.model_file == icub_urdf_path():
        return icub_mjcf_spec()
    return _spec_from_file(robot.model_file)


def _spec_from_file(path):
    if not os.path.isfile(str(path)):
        raise ModelError(f"robot model file '{path}' does not exist; RobotModel.model_file "
                         'must name the MJCF/URDF both pinocchio and MuJoCo load')
    try:
        return mujoco.MjSpec.from_file(str(path))
    except ValueError as exc:
        raise ModelError(f"MuJoCo could not load '{path}': {exc}") from exc


def mujoco_indices(robot: RobotModel, mj_model: Any) -> tuple[np.ndarray, np.ndarray]:
    """Return the MuJoCo ``qpos`` and ``dof`` addresses of ``robot``'s joints, in its order.

    ``q_mujoco[qpos_adr] = q`` maps a pinocchio configuration into MuJoCo (the iCub's joint
    order differs between the two; the KUKA and dual-arm files agree).

    Args:
        robot: A :class:`~ifc_spg.model.RobotModel`.
        mj_model: A compiled ``mujoco.MjModel`` containing the robot's joints by name.

    Raises:
        UnknownJoint: a joint of ``robot`` is not in ``mj_model``.
    """
    names = [mj_model.joint(i).name for i in range(mj_model.njnt)]
    qpos, dof = [], []
    for j in robot.joint_names:
        if j not in names:
            raise UnknownJoint(f"joint '{j}' of robot '{robot.name}' is not in the MuJoCo "
                               f'model{did_you_mean(j, names)}')
        k = names.index(j)
        qpos.append(int(mj_model.jnt_qposadr[k]))
        dof.append(int(mj_model.jnt_dofadr[k]))
    return np.array(qpos), np.array(dof)
