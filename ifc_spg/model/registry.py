"""Named robot configurations: the parameter tables behind ``RobotModel.from_config(name)``.

Every named robot is built from ONE model file that both pinocchio (the SPG) and MuJoCo
(the simulator) load, so the SPG and the simulation share kinematics and inertias exactly:

- ``lbr4``, ``lbr_iiwa14``, ``accrea_dual_arm``: MJCF files in ``ifc_spg/model/data/``,
  generated from the tables in this module by ``python -m ifc_spg.cli.generate``.
  MJCF (not URDF) is the shared format because it carries everything both sides need:
  sites (``flange``, ``tool``, F/T frames) become pinocchio operational frames, joint
  ``armature`` enters both mass matrices, ``actuatorfrcrange`` becomes pinocchio's
  ``effortLimit``, and MuJoCo keeps the body tree as written (a URDF is re-interpreted by
  MuJoCo: static links fused, no sites, inertias re-diagonalised).
- ``icub_upper_body``: the official iCub URDF of the ``icub-models`` wheel
  (``iCubGazeboV2_7``, CC-BY-SA-4.0, read in place, never copied), reduced to 17 joints;
  ``sim_bridge.models.icub_mjcf_spec`` gives MuJoCo the same file reduced the same way.

Velocity and acceleration limits are not representable in MJCF; they come from the
tables here. Joint names of the KUKA arms follow KUKA's axis names ``A1`` ... ``A7``.
This module is data: loading the files into MuJoCo (``mujoco.MjSpec``, joint addresses)
is the simulator's, in :mod:`sim_bridge.models`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math
import os
from typing import Any

import numpy as np
import pinocchio as pin

from ifc_spg.errors import ModelError, UnknownRobot, did_you_mean
from ifc_spg.model.ifc import CARTESIAN_ADMITTANCE, JOINT_IMPEDANCE, CartesianAdmittance

__all__ = [
    'ArmTable', 'Link', 'ROBOTS', 'LBR4', 'LBR_IIWA14', 'ACCREA_ARM', 'DATA_DIR',
    'ICUB_JOINTS', 'ICUB_FRAMES', 'ICUB_WIPE_PAD', 'ICUB_WIPE_ARM_DEG',
    'robot_arguments', 'model_file', 'icub_urdf_path', 'accrea_home_deg',
]

DATA_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'data')
ROBOTS = ('lbr4', 'lbr_iiwa14', 'icub_upper_body', 'accrea_dual_arm')


@dataclass(frozen=True)
class Link:
    """One moving link of a serial arm; all link frames are parallel to the base at q = 0.

    Attributes:
        pos: Origin of this link's frame (on its joint axis) in the parent frame [m].
        axis: Joint axis in the link frame (unit vector).
        mass: Link mass [kg].
        com: Centre of mass in the link frame [m].
        inertia: Principal moments about the centre of mass, axes parallel to the link
            frame [kg m^2].
        length: Length of the collision capsule along +z from the origin [m].
        radius: Radius of the collision capsule [m].
    """

    pos: tuple
    axis: tuple
    mass: float
    com: tuple
    inertia: tuple
    length: float
    radius: float


@dataclass(frozen=True)
class ArmTable:
    """The parameter table of one 7-DoF arm: kinematics, inertias, limits, IFC defaults.

    Attributes:
        name: Model name.
        base_mass: Mass of the fixed base link [kg] (no effect on the dynamics).
        base_com: Base centre of mass [m].
        base_inertia: Base principal moments [kg m^2].
        base_radius: Radius of the base collision cylinder [m].
        links: The seven moving links A1..A7.
        flange: Flange offset along z of link 7 [m].
        tool_length: Tool tip offset from the flange along z [m].
        tool_radius: Radius of the pen-like tool and its spherical tip [m].
        tool_mass: Mass of a separate tool body (0: tool geometry is massless, on link 7) [kg].
        q_max_deg: Symmetric joint position limits [deg].
        v_max_deg: Joint velocity limits [deg/s].
        a_max_deg: Joint acceleration limits [deg/s^2].
        tau_max: Joint torque limits [Nm].
        stiffness: Default joint stiffness K [Nm/rad].
        damping: Default joint damping D [Nms/rad] (about 0.7 * 2 * sqrt(K M_ii(q_home))).
        q_home_deg: Home configuration [deg].
        armature: Reflected rotor inertia per joint [kg m^2], in both mass matrices.
        joint_damping: Passive viscous joint damping in the simulation [Nms/rad].
    """

    name: str
    base_mass: float
    base_com: tuple
    base_inertia: tuple
    base_radius: float
    links: tuple
    flange: float
    tool_length: float
    tool_radius: float
    tool_mass: float
    q_max_deg: tuple
    v_max_deg: tuple
    a_max_deg: tuple
    tau_max: tuple
    stiffness: tuple
    damping: tuple
    q_home_deg: tuple
    armature: float
    joint_damping: float


_Z, _Y, _NY = (0.0, 0.0, 1.0), (0.0, 1.0, 0.0), (0.0, -1.0, 0.0)

# KUKA LBR iiwa 14 R820. Kinematics: 0.36 / 0.42 / 0.40 / 0.126 m (base-shoulder,
# shoulder-elbow, elbow-wrist, wrist-flange), axes z, y, z, -y, z, y, z. Inertial values:
# the identified iiwa 14 parameters published with the MuJoCo Menagerie model
# (kuka_iiwa_14, 30.6 kg incl. 5 kg base), expressed in base-parallel link frames.
# Limits: KUKA datasheet; the acceleration limit is not published (assumed as LBR-IV).
LBR_IIWA14 = ArmTable(
    name='lbr_iiwa14',
    base_mass=5.0, base_com=(-0.1, 0.0, 0.07), base_inertia=(0.05, 0.06, 0.03),
    base_radius=0.11,
    links=(
        Link((0, 0, 0.1575), _Z, 5.76, (0, -0.03, 0.12), (0.0333, 0.033, 0.0123), 0.2025, 0.075),
        Link((0, 0, 0.2025), _Y, 6.35, (-0.0003, 0.042, 0.059), (0.0305, 0.011, 0.0304),
             0.2045, 0.075),
        Link((0, 0, 0.2045), _Z, 3.5, (0, 0.03, 0.13), (0.025, 0.0238, 0.0076), 0.2155, 0.07),
        Link((0, 0, 0.2155), _NY, 3.5, (0, -0.034, 0.067), (0.017, 0.006, 0.0164), 0.1845, 0.07),
        Link((0, 0, 0.1845), _Z, 3.5, (-0.0001, -0.021, 0.076), (0.01, 0.0087, 0.00449),
             0.2155, 0.06),
        Link((0, 0, 0.2155), _Y, 1.8, (0, 0.0004, 0.0006), (0.0049, 0.0036, 0.0047), 0.081, 0.06),
        Link((0, 0, 0.081), _Z, 1.2, (0, 0, 0.02), (0.001, 0.001, 0.001), 0.045, 0.045),
    ),
    flange=0.045, tool_length=0.1, tool_radius=0.01, tool_mass=0.0,
    q_max_deg=(170, 120, 170, 120, 170, 120, 175),
    v_max_deg=(85, 85, 100, 75, 130, 135, 135),
    a_max_deg=(500,) * 7,
    tau_max=(320, 320, 176, 176, 110, 40, 40),
    stiffness=(200.0,) * 7,
    damping=(30.0, 39.0, 16.0, 17.0, 3.7, 3.2, 2.1),
    q_home_deg=(0, 30, 0, -60, 0, 90, 0),
    armature=0.01, joint_damping=0.1,
)

# KUKA LBR-IV (LWR 4). Kinematics: 0.31 / 0.40 / 0.39 / 0.078 m. No inertias are
# published: the iiwa 14 distribution scaled to the LBR-IV's segment lengths and ~15 kg
# (14 kg moving links + 1 kg base). Limits: thesis Table B.1 (docs/SPEC.md §8).
LBR4 = ArmTable(
    name='lbr4',
    base_mass=1.0, base_com=(0, 0, 0.05), base_inertia=(0.004, 0.004, 0.003),
    base_radius=0.08,
    links=(
        Link((0, 0, 0.11), _Z, 2.7, (0, -0.0296, 0.1185), (0.01523, 0.01509, 0.00562), 0.2, 0.065),
        Link((0, 0, 0.2), _Y, 2.7, (-0.0003, 0.0411, 0.0577), (0.0124, 0.00447, 0.01236), 0.2,
             0.065),
        Link((0, 0, 0.2), _Z, 2.5, (0, 0.0278, 0.1206), (0.01538, 0.01464, 0.00468), 0.2, 0.06),
        Link((0, 0, 0.2), _NY, 2.4, (0, -0.034, 0.067), (0.01166, 0.00411, 0.01125), 0.2, 0.06),
        Link((0, 0, 0.2), _Z, 1.7, (-0.0001, -0.0185, 0.067), (0.00378, 0.00328, 0.0017), 0.19,
             0.055),
        Link((0, 0, 0.19), _Y, 1.6, (0, 0.0003, 0.0005), (0.00279, 0.00205, 0.00267), 0.0, 0.055),
        Link((0, 0, 0.0), _Z, 0.4, (0, 0, 0.02), (0.00033, 0.00033, 0.00033), 0.078, 0.04),
    ),
    flange=0.078, tool_length=0.1, tool_radius=0.01, tool_mass=0.0,
    q_max_deg=(170, 120, 170, 120, 170, 105, 170),
    v_max_deg=(20,) * 7,
    a_max_deg=(500,) * 7,
    tau_max=(50,) * 7,
    stiffness=(200.0,) * 7,
    damping=(23.0, 30.0, 12.0, 13.0, 2.5, 2.2, 2.0),
    q_home_deg=(0, 30, 0, -60, 0, 90, 0),
    armature=0.01, joint_damping=0.1,
)


def _scaled_arm(table, *, name, length, mass, tau):
    """Return ``table`` with lengths scaled by ``length`` and masses by ``mass``."""
    links = tuple(
        replace(lk, pos=tuple(length * x for x in lk.pos), mass=mass * lk.mass,
                com=tuple(length * x for x in lk.com),
                inertia=tuple(mass * length ** 2 * x for x in lk.inertia),
                length=length * lk.length, radius=length * lk.radius)
        for lk in table.links)
    return replace(
        table, name=name, links=links, base_mass=mass * table.base_mass,
        base_com=tuple(length * x for x in table.base_com),
        base_inertia=tuple(mass * length ** 2 * x for x in table.base_inertia),
        base_radius=length * table.base_radius, flange=length * table.flange,
        tau_max=tuple(tau * x for x in table.tau_max))


# One arm of the ACCREA-like dual-arm robot: the iiwa 14 table scaled to 0.6 in length and
# 0.25 in mass (6.4 kg of moving links per arm), torque limits scaled by 0.25; a 0.3 kg wrist
# F/T sensor and tool body after the flange (the F/T sensor measures its weight). Its joint
# stiffness/damping are the gains of the inner joint position loop of the admittance
# emulation (the SPG uses the Cartesian admittance parameters below).
ACCREA_ARM = replace(
    _scaled_arm(LBR_IIWA14, name='accrea_arm', length=0.6, mass=0.25, tau=0.25),
    tool_length=0.12, tool_mass=0.3, armature=0.005,
    stiffness=(1000.0,) * 7, damping=(20.0,) * 7,
    q_home_deg=(-15, 90, -90, 45, 0, -60, 0))

# Torso of the dual-arm robot (a fixed box from the floor to 1.3 m, half sizes [m]); the arm
# bases are mounted on its sides at ACCREA_SHOULDER = (x, +-y, z) [m], each arm's A1 axis
# pointing outwards (left +y, right -y).
ACCREA_SHOULDER = (0.0, 0.12, 1.2)
ACCREA_TORSO: dict[str, Any] = dict(mass=20.0, size=(0.1, 0.12, 0.65))

# Cartesian admittance defaults per tool chain: K_x [N/m]*3 + [Nm/rad]*3, M_x [kg]*3 +
# [kg m^2]*3, D_x [Ns/m]*3 + [Nms/rad]*3. D_x is sized for a rigid grasp, not for
# critical damping of M_x/K_x: grasping a drawer, door or crank closes a force loop through
# the inner position servo's Cartesian stiffness K_c (~2e4 N/m, ~3e3 Nm/rad for the
# emulation's servos), whose damping ratio is D_x / (2 sqrt(K_c M_x)); the critically damped
# 2 sqrt(K_x M_x) gives sqrt(K_x / K_c) ~ 0.16 for any M_x and oscillated (+-40 N). These
# give ~0.75 (translation) and ~0.7 (rotation); in free space the admittance is then
# overdamped (slow pole K_x / D_x ~ 1.7 rad/s, force following at 1 / D_x = 3.3 mm/s per N).
_ACCREA_K_X = (500.0,) * 3 + (50.0,) * 3
_ACCREA_M_X = (2.0,) * 3 + (0.1,) * 3
_ACCREA_D_X = (300.0,) * 3 + (25.0,) * 3


def _accrea_admittance():
    return CartesianAdmittance(stiffness=np.array(_ACCREA_K_X), damping=np.array(_ACCREA_D_X),
                               mass=np.array(_ACCREA_M_X))


# iCub upper body (thesis 3.3.2, docs/SPEC.md §8).
ICUB_MODEL = 'iCubGazeboV2_7'
_ICUB_ARM = ('shoulder_pitch', 'shoulder_roll', 'shoulder_yaw', 'elbow', 'wrist_prosup',
             'wrist_pitch', 'wrist_yaw')
ICUB_TORSO = ('torso_pitch', 'torso_roll', 'torso_yaw')
ICUB_JOINTS = ICUB_TORSO + tuple(f'{s}_{j}' for s in 'lr' for j in _ICUB_ARM)
ICUB_STIFF = tuple(f'{s}_{j}' for s in 'lr' for j in _ICUB_ARM[4:])
# Added frames: name -> (URDF link, translation [m] in that link's frame). The contact
# point is the wrist centre on the forearm (the iCub forearm DH frame: moved by torso,
# shoulder, elbow and prosup, not by wrist pitch/yaw), the palm the iCub hand DH frame.
ICUB_FRAMES = {
    f'{s}_{what}': (f'{s}_{link}', (0.0, 0.0, 0.0))
    for s in 'lr' for what, link in (('contact', 'forearm_dh_frame'), ('palm', 'hand_dh_frame'))
}
# iCub joint limits beyond the URDF (whose effort/velocity entries are placeholders 5e4):
# assumed, of the order of the iCub motor-control configuration files.
_ICUB_V_MAX_DEG = (50.0,) * 3 + (100.0,) * 14
_ICUB_TAU_MAX = (40.0, 40.0, 20.0) + (20.0, 20.0, 10.0, 10.0, 2.0, 2.0, 2.0) * 2
_ICUB_HOME_DEG = (0.0, 0.0, 0.0) + (-30.0, 30.0, 0.0, 45.0, 0.0, 0.0, 0.0) * 2
# Wiping pad (Table 3.7): a sphere on the left forearm link, i.e. on the last compliant link
# of chain LW (l_contact), so the table touches the robot at the end of the force chain as
# the thesis' static model assumes ("force tasks are executed at the wrist only"); the iCub
# fingers, behind the stiff wrist joints, would touch it off the chain. Body, centre [m] in
# the ``l_forearm_dh_frame`` (= l_contact) frame, radius [m]: the centre lies 5.0 cm straight
# below l_contact, the pad's lowest point 6.5 cm below it (1.2 cm below the fingers), in the
# wiping posture ICUB_WIPE_ARM_DEG (prosup 25 deg; in other postures the offset turns with
# the forearm). Collision only: no mass, not in the SPG's model.
ICUB_WIPE_PAD = ('l_forearm_dh_frame', (-0.0479, 0.0098, 0.0104), 0.015)
#: Left arm joints [deg] (shoulder pitch roll yaw, elbow, wrist prosup pitch yaw) of the
#: Table 3.7 wiping posture: mid-range joints, the hand reaching forward and down.
ICUB_WIPE_ARM_DEG = (-30.0, 45.0, 45.0, 60.0, 25.0, 0.0, 0.0)


def model_file(name: str) -> str:
    """Return the path of the shared model file of robot ``name``.

    Args:
        name: One of :data:`ROBOTS`.
    """
    _check_name(name)
    if name == 'icub_upper_body':
        return icub_urdf_path()
    return os.path.join(DATA_DIR, f'{name}.xml')


def robot_arguments(name: str) -> dict[str, Any]:
    """The :class:`~ifc_spg.model.RobotModel` constructor arguments of configuration ``name``.

    ``RobotModel.from_config(name)`` builds the model from them (this module is data: it
    does not import the class).

    Args:
        name: One of :data:`ROBOTS`.

    Raises:
        UnknownRobot: ``name`` is not a known configuration.
    """
    _check_name(name)
    if name == 'icub_upper_body':
        return _load_icub()
    if name == 'accrea_dual_arm':
        return _load_accrea()
    table = LBR4 if name == 'lbr4' else LBR_IIWA14
    return dict(
        model=_mjcf_model(model_file(name)), model_file=model_file(name), name=name,
        frames={'flange': 'flange', 'tool': 'tool'},
        stiffness=table.stiffness, damping=table.damping, v_max=_deg(table.v_max_deg),
        a_max=_deg(table.a_max_deg), q_home=_deg(table.q_home_deg), ifc=JOINT_IMPEDANCE)


def _load_accrea():
    a = ACCREA_ARM
    frames = {f'{s}_{f}': f'{s}_{f}' for s in 'lr' for f in ('flange', 'ft', 'tool')}
    adm = _accrea_admittance()
    return dict(
        model=_mjcf_model(model_file('accrea_dual_arm')),
        model_file=model_file('accrea_dual_arm'), name='accrea_dual_arm', frames=frames,
        stiffness=a.stiffness * 2, damping=a.damping * 2, v_max=_deg(a.v_max_deg * 2),
        a_max=_deg(a.a_max_deg * 2), q_home=_deg(accrea_home_deg()),
        ifc=CARTESIAN_ADMITTANCE, admittance={'l_tool': adm, 'r_tool': adm})


def accrea_home_deg() -> tuple[float, ...]:
    """Home configuration of the dual arm [deg]: the right arm mirrors the left one."""
    left = ACCREA_ARM.q_home_deg
    # The right mount is the left one reflected in the x-z plane and in the arm's own x-z
    # plane: joints about the arm's z axis (A1, A3, A5, A7) change sign, A2, A4, A6 do not.
    right = tuple(-q if i % 2 == 0 else q for i, q in enumerate(left))
    return left + right


def _mjcf_model(path):
    return pin.buildModelFromMJCF(str(path))


def _deg(values):
    return np.radians(np.asarray(values, dtype=float))


def _check_name(name):
    if name not in ROBOTS:
        raise UnknownRobot(f"unknown robot '{name}'{did_you_mean(name, ROBOTS)}; available: "
                           f"{', '.join(ROBOTS)}")


# -- iCub -----------------------------------------------------------------------------------
def icub_urdf_path() -> str:
    """Return the path of the iCub URDF shipped in the ``icub-models`` wheel."""
    try:
        import icub_models  # type: ignore[import-untyped]  # the wheel ships no type hints
    except ImportError as exc:
        raise ModelError("robot 'icub_upper_body' needs the icub-models wheel; "
                         'pip install icub-models') from exc
    return str(icub_models.get_model_file(ICUB_MODEL))


def _load_icub():
    urdf = icub_urdf_path()
    model = pin.buildModelFromUrdf(urdf)
    names = list(model.names[1:])
    for j in ICUB_JOINTS:
        if j not in names:
            raise ModelError(f"iCub URDF '{urdf}' has no joint '{j}'{did_you_mean(j, names)}")
    lock = [model.getJointId(j) for j in names if j not in ICUB_JOINTS]
    model = pin.buildReducedModel(model, lock, pin.neutral(model))
    for fname, (link, offset) in ICUB_FRAMES.items():
        parent = model.getFrameId(link)
        f = model.frames[parent]
        placement = f.placement * pin.SE3(np.eye(3), np.asarray(offset, dtype=float))
        model.addFrame(pin.Frame(fname, f.parentJoint, parent, placement,
                                 pin.FrameType.OP_FRAME))
    # pinocchio orders the joints by its own tree traversal: look the tables up by name.
    order = list(model.names[1:])
    v_max = _reorder(_ICUB_V_MAX_DEG, order)
    tau = _reorder(_ICUB_TAU_MAX, order)
    home = _reorder(_ICUB_HOME_DEG, order)
    stiffness = np.array([50.0 if j in ICUB_TORSO else 5.0 for j in order])
    damping = np.array([0.5 if j in ICUB_TORSO else 0.2 for j in order])
    frames = {f: f for f in ICUB_FRAMES}
    frames.update({f'{s}_hand': f'{s}_hand' for s in 'lr'})
    return dict(
        model=model, name='icub_upper_body', frames=frames, stiffness=stiffness, damping=damping,
        v_max=_deg(v_max), a_max=math.radians(500.0), tau_max=tau, stiff_joints=ICUB_STIFF,
        q_home=_deg(home), ifc=JOINT_IMPEDANCE, model_file=urdf)


def _reorder(values, order):
    by_name = dict(zip(ICUB_JOINTS, values))
    return np.array([by_name[j] for j in order], dtype=float)
