"""The simulated robot: a MuJoCo robot + scene driven by one of the three IFC emulations.

:class:`Simulation` implements :class:`~sim_bridge.interface.RobotInterface`. Physics runs
at ``timestep`` (default 1 kHz), the IFC law at every physics step, and the command q_v is
held between updates (zero-order hold; the node writes it at 500 Hz). One physics step is::

    mj_step1          kinematics, qfrc_bias (gravity + Coriolis) at the current state
    law.control       IFC: compensation torques, admittance/IK (actuators hold K, D)
    pushes            person-like wrenches -> xfrc_applied
    mj_step2          constraint forces, sensors, integration (implicitfast, elliptic cones)
    latches           break-away doors release/re-engage
    (fri_delay > 0)   at a period boundary, the command due now starts to act

The robot base frame is the world frame (robot root body at the origin, as pinocchio
assumes). Commands are checked once per ``command_period``: a period that starts without
a new command (after the first one) keeps the last q_v and is counted in
``State.missed_commands``.

FRI loop delay (``fri_delay``, ``lbr_fri`` only): a command is applied ``fri_delay`` whole
command periods (FRI periods) after the period boundary at which it is sent; the state read
at a period's start is the one the client answers. ``0`` (the default) applies a command
sent at a period's start during that same period: a client that answers instantly. ``1`` is
a client that answers at the end of the period: the command computed from the state of
period k acts from period k + 1 on; n > 1 models a client or network slower than that.
Source: KUKA's Sunrise.Connectivity FRI Client SDK 1.14 (``friClientApplication.h``,
``ClientApplication::step``; public copy at github.com/lbr-stack/fri) describes one
processing step per period as "receiving a new FRI monitoring message, calling the
corresponding client callback and sending the resulting FRI command message back to the
KUKA Sunrise controller": one command answers each state. Neither the SDK nor any other
KUKA text we found (the FRI manuals are not public) says in which controller cycle the
answer takes effect, so the delay in periods is not KUKA's number: the default 0 (the
emulation as it was, bit for bit) is our choice, and 1 is the conservative setting for a
client that uses its whole period.
"""

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
import math
from typing import Any

import mujoco
import numpy as np

from ifc_spg.errors import ModelError, ParameterError, UnknownFrame, did_you_mean
from ifc_spg.model import RobotModel
from sim_bridge.cartesian_admittance import CartesianAdmittanceLaw
from sim_bridge.interface import RobotInterface, State, check_fri_delay, check_vector
from sim_bridge.joint_impedance import JointImpedance
from sim_bridge.robot_spec import load_robot_spec
from sim_bridge.scenes import Anchor, build_scene

__all__ = ['INTERFACES', 'SimConfig', 'Simulation', 'default_interface']

INTERFACES = ('lbr_fri', 'icub', 'accrea')
_EXTERNAL_CONSTRAINTS = (
    mujoco.mjtConstraint.mjCNSTR_EQUALITY, mujoco.mjtConstraint.mjCNSTR_CONTACT_FRICTIONLESS,
    mujoco.mjtConstraint.mjCNSTR_CONTACT_PYRAMIDAL, mujoco.mjtConstraint.mjCNSTR_CONTACT_ELLIPTIC)
# the same set as a lookup table indexed by a constraint's type (one gather per step, where
# np.isin sorts both operands: 70 us a call)
_EXTERNAL_MASK = np.zeros(max(map(int, mujoco.mjtConstraint.__members__.values())) + 1, dtype=bool)
_EXTERNAL_MASK[[int(c) for c in _EXTERNAL_CONSTRAINTS]] = True


def default_interface(model: RobotModel) -> str:
    """The IFC emulation a robot model implies: accrea, icub (stiff joints) or lbr_fri."""
    if model.ifc == 'cartesian_admittance':
        return 'accrea'
    return 'icub' if np.any(model.stiff_mask) else 'lbr_fri'


# a gain or property per joint, or one for all joints
PerJoint = float | Sequence[float] | np.ndarray


@dataclass(frozen=True)
class SimConfig:
    """Everything that defines a simulation run (validated by :class:`Simulation`).

    Attributes:
        robot: Robot configuration name (``lbr_iiwa14``, ``lbr4``, ``icub_upper_body``,
            ``accrea_dual_arm``) or a :class:`~ifc_spg.model.robot_model.RobotModel`.
        interface: ``lbr_fri``, ``icub`` or ``accrea``; ``None``: implied by the robot.
        scene: Scene name (see :mod:`sim_bridge.scenes`).
        scene_options: Scene builder options.
        q0: Initial joint positions in [rad]; ``None``: the robot's home pose. Scenes are
            anchored at the tool pose of q0.
        timestep: Physics step in [s] (<= 0.001).
        command_period: Command update period in [s] (a multiple of ``timestep``).
        stiffness: Joint stiffness K override in [Nm/rad] (scalar or per joint).
        damping: IFC joint damping D override in [Nms/rad].
        joint_damping: Physical viscous joint damping override in [Nms/rad].
        frictionloss: Physical static (Coulomb) joint friction override in [Nm].
        armature: Reflected rotor inertia override in [kg m^2].
        stiff_gains: (K_p, K_d) of the position-controlled (stiff) iCub joints.
        admittance: Chain id -> :class:`~ifc_spg.model.robot_model.CartesianAdmittance`
            override (default: the robot model's parameters).
        admittance_gains: Keyword options of
            :class:`~sim_bridge.cartesian_admittance.CartesianAdmittanceLaw`.
        contact_chain: Chain whose tool reports ``contact_wrench`` (default: ``tool`` or the
            first chain with an F/T sensor, else the first chain).
        fri_delay: FRI loop delay in whole command periods (int >= 0; ``lbr_fri`` only): a
            command acts ``fri_delay`` periods after the period boundary it is sent at (see
            the module docstring; 0: in the same period, our default).
    """

    robot: str | RobotModel = 'lbr_iiwa14'
    interface: str | None = None
    scene: str = 'free'
    scene_options: dict[str, Any] = field(default_factory=dict)  # scene options, from JSON
    q0: Sequence[float] | None = None
    timestep: float = 0.001
    command_period: float = 0.002
    stiffness: PerJoint | None = None
    damping: PerJoint | None = None
    joint_damping: PerJoint | None = None
    frictionloss: PerJoint | None = None
    armature: PerJoint | None = None
    stiff_gains: tuple[float, float] = (2000.0, 20.0)
    admittance: dict[str, Any] | None = None  # keyword options, from YAML/JSON
    admittance_gains: dict[str, Any] = field(default_factory=dict)
    contact_chain: str | None = None
    fri_delay: int = 0


def _per_joint(value: 'PerJoint | None', n: int, what: str,
               names: Sequence[str]) -> np.ndarray | None:
    if value is None:
        return None
    a = np.asarray(value, dtype=float)
    a = np.full(n, float(a.reshape(-1)[0])) if a.size == 1 else a.reshape(-1)
    if a.shape != (n,) or not np.all(np.isfinite(a)) or np.any(a < 0):
        raise ParameterError(f'{what} must be one number or {n} numbers >= 0 (joints '
                             f'{", ".join(names)}), got {value!r}')
    return a


def _load_model(robot: str | RobotModel) -> RobotModel:
    """The RobotModel of a configuration name, or ``robot`` itself."""
    if isinstance(robot, str):
        return RobotModel.from_config(robot)
    return robot


class Simulation(RobotInterface):
    """A MuJoCo robot + scene behind the reset/read_state/write_command/close interface.

    Args:
        config: A :class:`SimConfig`.

    Raises:
        ParameterError: A bad interface, scene, timing or override.
        ModelError: The robot model cannot be loaded into MuJoCo.
    """

    def __init__(self, config: SimConfig | None = None, **overrides: Any) -> None:
        config = SimConfig(**overrides) if config is None else config
        self.config = config
        self.robot = _load_model(config.robot)
        robot = self.robot
        self.interface = config.interface or default_interface(robot)
        if self.interface not in INTERFACES:
            raise ParameterError(f"unknown interface '{self.interface}'"
                                 f"{did_you_mean(self.interface, INTERFACES)}; choose one of "
                                 f"{', '.join(INTERFACES)}")
        if self.interface == 'accrea' and not robot.admittance:
            raise ParameterError(f"interface 'accrea' needs a robot with Cartesian admittance "
                                 f"parameters; '{robot.name}' has none (use interface "
                                 "'lbr_fri' or robot 'accrea_dual_arm')")
        if not 0.0 < config.timestep <= 0.001:
            raise ParameterError(f'timestep must be in (0, 0.001] s (physics >= 1 kHz), got '
                                 f'{config.timestep}')
        ratio = config.command_period / config.timestep
        if ratio < 1.0 - 1e-9 or abs(ratio - round(ratio)) > 1e-6:
            raise ParameterError(f'command_period {config.command_period} s must be a multiple '
                                 f'of timestep {config.timestep} s')
        self.fri_delay = check_fri_delay(config.fri_delay)
        if self.fri_delay and self.interface != 'lbr_fri':
            raise ParameterError(f"fri_delay is a parameter of the 'lbr_fri' interface, not "
                                 f"'{self.interface}'; leave it 0")
        self.dt = float(config.timestep)
        self._steps_per_command = round(ratio)
        self.joint_names: tuple[str, ...] = tuple(robot.joint_names)
        n = len(self.joint_names)
        q0 = robot.q_home if config.q0 is None else check_vector(config.q0, n, 'q0',
                                                                 self.joint_names)
        self.q0 = np.array(q0, dtype=float)
        self._build(config)
        self._closed = False
        self.reset(self.q0)

    # -- construction --------------------------------------------------------------------
    def _build(self, config):
        """Load the robot, add the scene and the actuators, compile, index, make the law."""
        robot = self.robot
        rspec = load_robot_spec(robot)
        self.robot_spec = rspec
        spec = rspec.spec
        self._override_joints(spec, config)
        self.contact_chain = contact_chain = self._pick_contact_chain(rspec, config)
        anchor = self._anchor(spec, rspec, contact_chain)
        self.scene = build_scene(spec, config.scene, anchor, config.scene_options)
        self._add_actuators(spec)
        try:
            self.model = spec.compile()
        except ValueError as exc:
            raise ModelError(f"MuJoCo could not compile robot '{robot.name}' with scene "
                             f"'{config.scene}': {exc}") from exc
        self._index(self.model, rspec, contact_chain)
        self.law = self._make_law(config)
        self.law.setup(self)

    def _override_joints(self, spec, config):
        """Apply the configured joint damping, friction loss and armature (per joint)."""
        names = self.joint_names
        n = len(names)
        overrides = {k: _per_joint(getattr(config, k), n, k, names)
                     for k in ('joint_damping', 'frictionloss', 'armature')}
        for i, jname in enumerate(names):
            joint = spec.joint(jname)
            if overrides['joint_damping'] is not None:
                joint.damping = [overrides['joint_damping'][i], 0.0, 0.0]
            if overrides['frictionloss'] is not None:
                joint.frictionloss = overrides['frictionloss'][i]
            if overrides['armature'] is not None:
                joint.armature = overrides['armature'][i]

    def _pick_contact_chain(self, rspec, config):
        """The configured contact chain, else the tool, an admittance chain, an F/T chain."""
        robot = self.robot
        chains = list(rspec.chain_sites)
        if config.contact_chain is not None:
            if config.contact_chain not in rspec.chain_sites:
                raise UnknownFrame(f"contact_chain '{config.contact_chain}' not a chain of "
                                   f"'{robot.name}'{did_you_mean(config.contact_chain, chains)}"
                                   f"; chains: {', '.join(chains)}")
            return config.contact_chain
        preferred = ['tool'] + [c for c in chains if c in robot.admittance] + list(
            rspec.ft_sensors) + chains
        return next(c for c in preferred if c in rspec.chain_sites)

    def _add_actuators(self, spec):
        """One affine position actuator per joint, and the solver options."""
        for jname in self.joint_names:
            spec.add_actuator(name=f'ifc_{jname}', target=jname,
                              trntype=mujoco.mjtTrn.mjTRN_JOINT,
                              gaintype=mujoco.mjtGain.mjGAIN_FIXED,
                              biastype=mujoco.mjtBias.mjBIAS_AFFINE,
                              ctrllimited=mujoco.mjtLimited.mjLIMITED_FALSE)
        spec.option.timestep = self.dt
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
        # Elliptic friction cones: exact Coulomb cones, and the only cone for which a
        # contact pair's separate friction reference (solreffriction) applies; the scenes
        # use it against sliding-contact chatter (see sim_bridge.scenes).
        spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
        spec.option.impratio = 10.0

    def _index(self, m, rspec, contact_chain):
        """Data and the addresses of joints, actuators, sites, sensors in the model ``m``."""
        names = self.joint_names
        self.data = mujoco.MjData(m)
        self._kin_data = mujoco.MjData(m)
        jids = [m.joint(j).id for j in names]
        qadr = np.array([m.jnt_qposadr[j] for j in jids])
        dadr = np.array([m.jnt_dofadr[j] for j in jids])
        self.qpos_index = _as_slice(qadr)
        self.dof_index = _as_slice(dadr)
        self.actuator_ids = np.array([m.actuator(f'ifc_{j}').id for j in names])
        self.actuator_index = _as_slice(self.actuator_ids)
        env = [m.joint(j) for j in self.scene.env_joints]
        self.env_joint_names = tuple(self.scene.env_joints)
        self._env_qadr = np.array([m.jnt_qposadr[j.id] for j in env], dtype=int)
        self._env_dadr = np.array([m.jnt_dofadr[j.id] for j in env], dtype=int)
        self._chain_site_ids = {c: m.site(s).id for c, s in rspec.chain_sites.items()}
        self._ft = {}
        for chain, ft in rspec.ft_sensors.items():
            body = m.body(ft.body).id
            self._ft[chain] = (
                m.site(ft.site).id, m.sensor_adr[m.sensor(ft.force).id],
                m.sensor_adr[m.sensor(ft.torque).id], body, float(m.body_subtreemass[body]))
        tool_body = m.body(rspec.tool_bodies[contact_chain]).id
        self._tool_bodies = np.array([b for b in range(m.nbody) if _is_descendant(
            m, b, tool_body)], dtype=int)
        self._latches = [(m.jnt_qposadr[m.joint(la.joint).id], m.equality(la.equality).id,
                          la.torque) for la in self.scene.latches]
        self._gravity = np.array(m.opt.gravity)
        self._scratch6 = np.zeros(6)

    def _make_law(self, config):
        """The robot's controller: Cartesian admittance (accrea) or joint impedance."""
        robot = self.robot
        names = self.joint_names
        stiffness = robot.stiffness if config.stiffness is None else _per_joint(
            config.stiffness, len(names), 'stiffness', names)
        damping = robot.damping if config.damping is None else _per_joint(
            config.damping, len(names), 'damping', names)
        if self.interface == 'accrea':
            admittance = dict(robot.admittance)
            for chain, params in (config.admittance or {}).items():
                if chain not in admittance:
                    raise UnknownFrame(f"admittance override for chain '{chain}': not an "
                                       f"admittance chain of '{robot.name}'"
                                       f"{did_you_mean(chain, admittance)}; chains: "
                                       f"{', '.join(admittance)}")
                admittance[chain] = params
            return CartesianAdmittanceLaw(admittance, **config.admittance_gains)
        mask = np.array(robot.stiff_mask) if self.interface == 'icub' else \
            np.zeros(len(names), dtype=bool)
        return JointImpedance(np.array(stiffness, float), np.array(damping, float),
                              mask, tuple(config.stiff_gains), self.interface)

    def _anchor(self, spec, rspec, chain):
        """Tool pose at q0 from a throw-away compile of the bare robot."""
        m = spec.compile()
        d = mujoco.MjData(m)
        for j, q in zip(self.joint_names, self.q0):
            d.qpos[m.jnt_qposadr[m.joint(j).id]] = q
        mujoco.mj_kinematics(m, d)
        site = m.site(rspec.chain_sites[chain]).id
        return Anchor(tool_pos=d.site_xpos[site].copy(),
                      tool_rot=d.site_xmat[site].reshape(3, 3).copy(),
                      base_pos=np.zeros(3), tool_site=rspec.chain_sites[chain],
                      tool_body=rspec.tool_bodies[chain])

    # -- the interface -------------------------------------------------------------------
    def reset(self, q0: Sequence[float] | np.ndarray | None = None) -> None:
        """Reset to ``q0`` [rad] (default: the construction q0), at rest, pushes cleared.

        Scenes stay where they were built (at the tool pose of the construction q0).
        """
        self._check_open()
        q0 = self.q0 if q0 is None else check_vector(q0, len(self.joint_names), 'q0',
                                                     self.joint_names)
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        d.qpos[self.qpos_index] = q0
        # (body id, site id or None, wrench (6,), end time [s])
        self._pushes: list[tuple[int, int | None, np.ndarray, float]] = []
        self._latch_armed = [False] * len(self._latches)
        self._step_count = 0
        self._fresh_command = False
        self._commanded = False
        self.missed_commands = 0
        # commands sent and not yet applied (fri_delay > 0): (physics step due, q_v, qd_v)
        self._in_flight: deque[tuple[int, np.ndarray, Any]] = deque()
        self._q_v = np.array(q0, dtype=float)
        self.law.reset(self, self._q_v)
        mujoco.mj_forward(m, d)

    def write_command(self, q_v: Sequence[float] | np.ndarray,
                      qd_v: Sequence[float] | np.ndarray | None = None,
                      tau_offset: Sequence[float] | np.ndarray | None = None) -> None:
        """Send q_v [rad] (held until the next command); ``tau_offset`` [Nm]: iCub only.

        With ``fri_delay`` n > 0 the command acts from the n-th period boundary after the
        one it is sent at (a command sent mid-period counts from the next boundary); until
        then the previous q_v is held and ``State.q_v`` is the one acting.
        """
        self._check_open()
        q_v = check_vector(q_v, len(self.joint_names), 'q_v', self.joint_names)
        if tau_offset is not None and self.interface != 'icub':
            raise ParameterError(f"tau_offset is an input of the 'icub' interface only, not "
                                 f"'{self.interface}'")
        if self.fri_delay:
            spc = self._steps_per_command
            boundary = -(-self._step_count // spc)  # this or the next period boundary
            self._in_flight.append(((boundary + self.fri_delay) * spc, q_v, qd_v))
        else:
            self._q_v = q_v
            self.law.command(self, q_v, qd_v, tau_offset)
        self._fresh_command = True
        self._commanded = True

    def step(self, n: int = 1) -> None:
        """Advance ``n`` physics steps."""
        self._check_open()
        m, d, law = self.model, self.data, self.law
        for _ in range(int(n)):
            if self._step_count % self._steps_per_command == 0:
                if self._commanded and not self._fresh_command:
                    self.missed_commands += 1
                self._fresh_command = False
            mujoco.mj_step1(m, d)
            law.control(self)
            if self._pushes:
                self._apply_pushes()
            mujoco.mj_step2(m, d)
            if self._latches:
                self._update_latches()
            self._step_count += 1
            if self._in_flight and self._in_flight[0][0] <= self._step_count:
                self._apply_due()  # fri_delay: at the boundary, before anyone reads the state

    def _apply_due(self):
        """Apply the newest in-flight command that is due (fri_delay > 0; older ones expire)."""
        _, q_v, qd_v = self._in_flight.popleft()
        while self._in_flight and self._in_flight[0][0] <= self._step_count:
            _, q_v, qd_v = self._in_flight.popleft()
        self._q_v = q_v
        self.law.command(self, q_v, qd_v, None)

    def step_until(self, t: float) -> None:
        """Advance whole physics steps until the time reaches ``t`` [s] (within dt/2)."""
        n = math.floor((t - self.data.time) / self.dt + 0.5)
        if n > 0:
            self.step(n)

    def read_time(self) -> float:
        """Simulation time in [s]."""
        return float(self.data.time)

    def read_state(self) -> State:
        """Return the current :class:`~sim_bridge.interface.State`."""
        self._check_open()
        m, d = self.model, self.data
        dof = self.dof_index
        tau = d.qfrc_actuator[dof] + d.qfrc_applied[dof]
        ft_wrench, ft_frames, ft_external = {}, {}, {}
        for chain, (site, fadr, tadr, _, _) in self._ft.items():
            ft_wrench[chain] = np.concatenate([d.sensordata[fadr:fadr + 3],
                                               d.sensordata[tadr:tadr + 3]])
            ft_frames[chain] = m.site(site).name
            ft_external[chain] = self.ft_external(chain).copy()
        return State(
            t=float(d.time), joint_names=self.joint_names, q=d.qpos[self.qpos_index].copy(),
            qd=d.qvel[dof].copy(), tau_measured=tau, tau_ext_est=self._tau_ext(),
            q_v=self._q_v.copy(), ft_wrench=ft_wrench, ft_frames=ft_frames,
            ft_external=ft_external, contact_wrench=self.contact_wrench(),
            env_joint_names=self.env_joint_names, env_q=d.qpos[self._env_qadr].copy(),
            env_qd=d.qvel[self._env_dadr].copy(), missed_commands=self.missed_commands)

    def close(self) -> None:
        """Release the MuJoCo model and data."""
        self._closed = True
        self.model = self.data = self._kin_data = None

    def _check_open(self) -> None:
        if self._closed:
            raise ParameterError('this Simulation was closed; create a new one')

    # -- measurements --------------------------------------------------------------------
    def _tau_ext(self) -> np.ndarray:
        """External joint torque (environment on robot), FRI-like, in [Nm].

        Contact and equality (grasp) constraint forces mapped through the constraint
        Jacobian, plus pushes: ``qfrc_smooth − passive + bias − applied − actuator`` is
        exactly the joint-space image of ``xfrc_applied``. Joint friction, damping and
        limits are internal and excluded (an ideal estimator).
        """
        m, d = self.model, self.data
        res = np.zeros(m.nv)
        if d.nefc:
            mask = _EXTERNAL_MASK[d.efc_type]
            mujoco.mj_mulJacTVec(m, d, res, np.where(mask, d.efc_force, 0.0))
        res += d.qfrc_smooth - d.qfrc_passive + d.qfrc_bias - d.qfrc_applied - d.qfrc_actuator
        return res[self.dof_index].copy()

    def ft_external(self, chain):
        """External wrench on the tool from the F/T sensor of ``chain``, tool weight removed.

        Returns:
            ``[f; τ]`` in the base frame in [N, Nm], moment about the chain frame origin;
            what the environment exerts on the tool (static compensation: the tool's
            inertial forces are neglected).
        """
        site, fadr, tadr, body, mass = self._ft[chain]
        d = self.data
        rot = d.site_xmat[site].reshape(3, 3)
        p_s = d.site_xpos[site]
        weight = mass * self._gravity
        f = -(rot @ d.sensordata[fadr:fadr + 3]) - weight
        tau_s = -(rot @ d.sensordata[tadr:tadr + 3]) - _cross(d.subtree_com[body] - p_s, weight)
        p_c = d.site_xpos[self._chain_site_ids[chain]]
        out = self._scratch6
        out[:3] = f
        out[3:] = tau_s + _cross(p_s - p_c, f)
        return out

    def contact_wrench(self) -> np.ndarray:
        """Ground-truth wrench the environment exerts on the contact chain's tool.

        Sum of contact and equality (grasp) forces on the tool subtree (MuJoCo
        ``cfrc_ext``, pushes removed), base frame, moment about the chain frame, [N, Nm].
        """
        m, d = self.model, self.data
        out = np.zeros(6)
        if not (d.ncon or d.nefc or self._pushes):
            return out
        mujoco.mj_rnePostConstraint(m, d)
        b = self._tool_bodies
        p = d.site_xpos[self._chain_site_ids[self.contact_chain]]
        ext = d.cfrc_ext[b]
        push = d.xfrc_applied[b]
        ref = d.subtree_com[m.body_rootid[b]]
        out[:3] = (ext[:, 3:] - push[:, :3]).sum(axis=0)
        out[3:] = (ext[:, :3] - push[:, 3:]).sum(axis=0) + _cross_sum(ref - p, ext[:, 3:]) \
            - _cross_sum(d.xipos[b] - p, push[:, :3])
        return out

    def kinematics_data(self, q, jacobians=False):
        """Scratch ``MjData`` with the kinematics of robot configuration ``q`` (scene at 0).

        Args:
            q: Robot joint positions in [rad].
            jacobians: Also compute what ``mj_jac*`` needs (``mj_comPos``).
        """
        m, d = self.model, self._kin_data
        d.qpos[:] = m.qpos0
        d.qpos[self.qpos_index] = q
        mujoco.mj_kinematics(m, d)
        if jacobians:
            mujoco.mj_comPos(m, d)
        return d

    def forward_kinematics(self, q, site_ids):
        """Return [(p [m], R)] of ``site_ids`` at robot configuration ``q`` (scene at 0)."""
        m, d = self.model, self._kin_data
        d.qpos[:] = m.qpos0
        d.qpos[self.qpos_index] = q
        mujoco.mj_kinematics(m, d)
        return [(d.site_xpos[s].copy(), d.site_xmat[s].reshape(3, 3).copy()) for s in site_ids]

    def site_id(self, chain):
        """MuJoCo site id of chain ``chain``."""
        try:
            return self._chain_site_ids[chain]
        except KeyError:
            raise UnknownFrame(f"chain '{chain}' not in robot '{self.robot.name}'"
                               f"{did_you_mean(chain, self._chain_site_ids)}; chains: "
                               f"{', '.join(self._chain_site_ids)}") from None

    def chain_pose(self, chain):
        """Current (p [m], R) of the chain frame (world = base frame)."""
        s = self.site_id(chain)
        return self.data.site_xpos[s].copy(), self.data.site_xmat[s].reshape(3, 3).copy()

    def geom_ids(self, names):
        """MuJoCo geom ids of ``names`` (geom names of the compiled model).

        Raises:
            ParameterError: a name is not a geom of the model.
        """
        m = self.model
        known = [m.geom(i).name for i in range(m.ngeom)]
        ids = []
        for name in names:
            if name not in known:
                raise ParameterError(f"no geom '{name}' in the simulation of "
                                     f"'{self.robot.name}' with scene '{self.scene.name}'"
                                     f'{did_you_mean(name, known)}')
            ids.append(known.index(name))
        return ids

    def geom_contact(self, geoms, others, distmax=0.2):
        """Contacts between two sets of geom ids now: ``(count, normal force [N], distance)``.

        ``count``: MuJoCo contacts between a geom of ``geoms`` and one of ``others``;
        normal force: the sum of their normal forces (``mj_contactForce``); distance: the
        smallest signed distance over the pairs (``mj_geomDistance``, capped at
        ``distmax`` [m]; negative: penetration).
        """
        m, d = self.model, self.data
        a, b = set(geoms), set(others)
        count, force = 0, 0.0
        f6 = np.zeros(6)
        for i in range(d.ncon):
            c = d.contact[i]
            if (c.geom1 in a and c.geom2 in b) or (c.geom1 in b and c.geom2 in a):
                count += 1
                mujoco.mj_contactForce(m, d, i, f6)
                force += float(f6[0])
        dist = float(distmax)
        for g1 in geoms:
            for g2 in others:
                dist = min(dist, float(mujoco.mj_geomDistance(m, d, g1, g2, distmax, None)))
        return count, force, dist

    def warnings(self) -> dict[str, int]:
        """Return {warning name: count} of the MuJoCo warnings raised so far (nonzero only)."""
        counts = self.data.warning.number
        return {mujoco.mjtWarning(i).name: int(c) for i, c in enumerate(counts) if c}

    # -- pushes and latches --------------------------------------------------------------
    def apply_wrench(self, target, wrench_in_base, duration=math.inf):
        """Push ``target`` like a person would, for ``duration`` [s] from now.

        Args:
            target: A chain id (e.g. ``tool``), a site or a body name. On a site/chain the
                force acts at the site origin; on a body at its centre of mass.
            wrench_in_base: ``[f; τ]`` in the base frame in [N, Nm] (constant direction).
            duration: How long in [s]; ``inf`` until :meth:`clear_wrenches`.
        """
        self._check_open()
        m = self.model
        w = check_vector(wrench_in_base, 6, 'wrench_in_base', ('fx', 'fy', 'fz', 'tx', 'ty',
                                                                'tz'))
        if not duration > 0:
            raise ParameterError(f'push duration must be > 0 s, got {duration}')
        site = None
        if target in self._chain_site_ids:
            site = self._chain_site_ids[target]
        else:
            sites = [m.site(i).name for i in range(m.nsite)]
            bodies = [m.body(i).name for i in range(m.nbody)]
            if target in sites:
                site = m.site(target).id
            elif target not in bodies:
                raise UnknownFrame(f"push target '{target}' is not a chain, site or body"
                                   f"{did_you_mean(target, list(self._chain_site_ids) + sites)}"
                                   f"; chains: {', '.join(self._chain_site_ids)}")
        body = int(m.site_bodyid[site]) if site is not None else m.body(target).id
        self._pushes.append((body, site, w, self.data.time + duration))

    @property
    def active_pushes(self):
        """The pushes acting now: (body id, site id or None, wrench, end time [s]) each."""
        return tuple(self._pushes)

    def clear_wrenches(self) -> None:
        """Remove every push."""
        for body, *_ in self._pushes:
            self.data.xfrc_applied[body] = 0.0
        self._pushes = []

    def _apply_pushes(self):
        d = self.data
        t = d.time
        for body, *_ in self._pushes:
            d.xfrc_applied[body] = 0.0
        alive = []
        for push in self._pushes:
            body, site, w, t_end = push
            if t >= t_end - 1e-12:
                continue
            alive.append(push)
            torque = w[3:]
            if site is not None:
                torque = torque + _cross(d.site_xpos[site] - d.xipos[body], w[:3])
            d.xfrc_applied[body, :3] += w[:3]
            d.xfrc_applied[body, 3:] += torque
        self._pushes = alive

    def _update_latches(self):
        d = self.data
        for k, (qadr, eq, torque) in enumerate(self._latches):
            q = d.qpos[qadr]
            if d.eq_active[eq]:
                rows = np.nonzero((d.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY)
                                  & (d.efc_id == eq))[0]
                if rows.size and -d.efc_force[rows[0]] >= torque:
                    d.eq_active[eq] = 0
            elif q > 0.05:
                self._latch_armed[k] = True
            elif self._latch_armed[k] and q < 0.002:
                d.eq_active[eq] = 1
                self._latch_armed[k] = False


def _cross_sum(a, b):
    """Sum over rows of the cross products a_i x b_i ((n, 3) arrays)."""
    return np.array([(a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]).sum(),
                     (a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]).sum(),
                     (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]).sum()])


def _cross(a, b):
    """Cross product of two 3-vectors (faster than np.cross for single vectors)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


def _as_slice(idx):
    idx = np.asarray(idx, dtype=int)
    if idx.size and np.all(np.diff(idx) == 1):
        return slice(int(idx[0]), int(idx[-1]) + 1)
    return idx


def _is_descendant(m, body, root):
    while body > 0:
        if body == root:
            return True
        body = m.body_parentid[body]
    return body == root
