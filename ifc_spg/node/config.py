"""The SPG node's configuration: one frozen dataclass, one parameter table.

Every setting of ``spg_node`` is declared ONCE, in :data:`PARAMETERS` (ROS name, field of
:class:`SpgConfig`, description, range); the default is the dataclass field's default. The
node declares them with descriptors (:func:`declare_parameters`), the YAML files in
``config/<robot>.yaml`` only override, and the offline runner builds the same
:class:`SpgConfig` without ROS::

    config = SpgConfig(robot='lbr4', status_decimation=1)
    config = config_from_parameters({'robot': 'lbr4', 'pspm.enabled': False})

ROS parameter names are grouped with dots (``pspm.initial_energy``, ``topics.command``);
in a params file they are nested mappings under ``ros__parameters``.
"""

from collections.abc import Mapping
from dataclasses import dataclass, fields
import math
import os
import sys
from typing import Any, NamedTuple

from ifc_spg.errors import ParameterError, did_you_mean
from ifc_spg.model import robot_gains
from ifc_spg.pspm import PspmConfig
from ifc_spg.ros import COMMAND_INTERFACES, HOT_PATHS
from ifc_spg.ros.protocols import Node as RosNode

__all__ = ['SpgConfig', 'Param', 'PARAMETERS', 'SOLVERS', 'declare_parameters',
           'config_from_parameters', 'config_file']

SOLVERS = ('daqp', 'proxsuite', 'nullspace')
_ROBOTS = ('lbr4', 'lbr_iiwa14', 'icub_upper_body', 'accrea_dual_arm')


@dataclass(frozen=True)
class SpgConfig:
    """Validated settings of the SPG node (and of :class:`~ifc_spg.node.core.SpgRunner`).

    Attributes:
        robot: Named robot configuration (``RobotModel.from_config``).
        dt: SPG period dT in [s] (the joint-state period of the robot interface).
        solver: Cascade solver: 'daqp', 'proxsuite' or 'nullspace' (baseline).
        rho: Regularization of qdot_v per level (4.45), dimensionless.
        torque_limits: Add the implicit top-level task |tau_s| <= tau_max (4.3).
        velocity_box: Bound qdot_v by the joint velocity and acceleration limits (4.31-4.33);
            False: by the position limits only (the Ch. 3 nullspace mapping, Alg. C.1/C.2).
        pspm: Passive set-point modulation (energy tanks) on/off.
        pspm_initial_energy: E_r,init per joint in [J].
        pspm_max_energy: E_r,max per joint in [J].
        pspm_shuffle: dE_shuffle per tick in [J].
        pspm_shuffle_budget: b^2, total shuffled energy per joint in [J].
        pspm_max_power: Ceiling of the tanks' refill rate a task stack may ask for
            (``power_budget``) in [W]; 0: strictly passive (such stacks are rejected).
        stiffness: Joint stiffness K of the robot's impedance controller in [Nm/rad], one
            value per joint or one for all; () keeps the robot configuration's.
        damping: Joint damping D in [Nms/rad], likewise.
        watchdog_timeout: No joint state for longer than this [s] stops commanding; the
            next state restarts from the measured q. 0 disables the watchdog.
        status_decimation: Publish ``spg/status`` every N-th tick.
        diagnostics_period: Period of ``spg/diagnostics`` in [s].
        task_stack_file: A task-stack file to run from the start ('' for none).
        joint_states_topic: Input joint states.
        command_topic: Output virtual joint positions.
        task_stack_topic: Input task stacks (latched).
        status_topic: Output status JSON.
        diagnostics_topic: Output DiagnosticArray.
        enable: Command the robot (False: publish nothing, or the measured q with
            ``hold_when_disabled``; switching it on restarts from the measured q).
        hold_when_disabled: While disabled, command the measured q (a position controller
            that needs a command every period holds still).
        command_interface: The command message: 'joint_state' (sensor_msgs/JointState, the
            bridge's and lockstep's), 'float64_multi_array' (std_msgs/Float64MultiArray,
            ros2_control's JointGroupPositionController) or 'joint_trajectory'
            (trajectory_msgs/JointTrajectory, one point at dT, for trajectory controllers).
        command_joints: Joint order of the command (ros2_control's ``joints``); () keeps
            the robot configuration's.
        tick: 'joint_states' (one tick per joint state: lockstep simulation, FRI at the
            SPG's rate) or 'timer' (a tick every ``dt`` with the latest joint state, for
            robots whose states come at another rate; nothing is extrapolated).
        hot_path: How ``spg_node`` serves the joint states on rclpy: 'wait_set' (a loop
            waiting on them and taking each itself, everything else on the executor; no
            executor overhead per tick) or 'executor' (rclpy's SingleThreadedExecutor, or the
            EventsExecutor with ``IFC_SPG_RCLPY_EXECUTOR=events``, for all callbacks). The
            built-in backend serves them from its one wait either way.
        markers_rate: Rate of ``spg/markers`` in [Hz] (<= 30; 0: off).
        markers_frame: Frame id of ``spg/markers``.
    """

    robot: str = 'lbr_iiwa14'
    dt: float = 0.002
    solver: str = 'daqp'
    rho: float = 0.01
    torque_limits: bool = True
    velocity_box: bool = True
    pspm: bool = True
    pspm_initial_energy: float = 0.5
    pspm_max_energy: float = 2.0
    pspm_shuffle: float = 0.0
    pspm_shuffle_budget: float = 0.0
    pspm_max_power: float = 0.0
    stiffness: tuple = ()
    damping: tuple = ()
    watchdog_timeout: float = 0.05
    status_decimation: int = 10
    diagnostics_period: float = 1.0
    task_stack_file: str = ''
    joint_states_topic: str = 'joint_states'
    command_topic: str = 'command/joint_position'
    task_stack_topic: str = 'spg/task_stack'
    status_topic: str = 'spg/status'
    diagnostics_topic: str = 'spg/diagnostics'
    enable: bool = True
    hold_when_disabled: bool = False
    command_interface: str = 'joint_state'
    command_joints: tuple = ()
    tick: str = 'joint_states'
    hot_path: str = 'wait_set'
    markers_rate: float = 30.0
    markers_frame: str = 'world'

    def __post_init__(self) -> None:
        for p in PARAMETERS:
            value = getattr(self, p.field)
            if isinstance(_DEFAULTS[p.field], tuple) and isinstance(value, list):  # from JSON
                value = tuple(value)
                object.__setattr__(self, p.field, value)
            _check_value(p, value)
        self._check_choices()
        self.pspm_config()  # validates the energies (initial <= max)
        for p in PARAMETERS:
            if p.field.endswith('_topic') and not getattr(self, p.field):
                raise ParameterError(f"parameter '{p.name}' must name a topic, got ''")

    def _check_choices(self) -> None:
        """Raise ParameterError for a robot, solver, tick or command interface not known."""
        if self.robot not in _ROBOTS:
            raise ParameterError(f"parameter 'robot': unknown robot '{self.robot}'"
                                 f'{did_you_mean(self.robot, _ROBOTS)}; choose one of '
                                 f"{', '.join(_ROBOTS)}")
        if self.solver not in SOLVERS:
            raise ParameterError(f"parameter 'solver': '{self.solver}' is not one of "
                                 f"{', '.join(SOLVERS)}{did_you_mean(self.solver, SOLVERS)}")
        if self.tick not in TICKS:
            raise ParameterError(f"parameter 'tick': '{self.tick}' is not one of "
                                 f"{', '.join(TICKS)}{did_you_mean(self.tick, TICKS)}")
        if self.hot_path not in HOT_PATHS:
            raise ParameterError(f"parameter 'hot_path': '{self.hot_path}' is not one of "
                                 f"{', '.join(HOT_PATHS)}"
                                 f'{did_you_mean(self.hot_path, HOT_PATHS)}')
        if self.command_interface not in COMMAND_INTERFACES:
            raise ParameterError(
                f"parameter 'command.interface': '{self.command_interface}' is not one of "
                f"{', '.join(COMMAND_INTERFACES)}"
                f'{did_you_mean(self.command_interface, COMMAND_INTERFACES)}')

    def pspm_config(self) -> PspmConfig | bool:
        """The :class:`~ifc_spg.pspm.PspmConfig`, or False when PSPM is off."""
        if not self.pspm:
            return False
        return PspmConfig(initial_energy=float(self.pspm_initial_energy),
                          max_energy=float(self.pspm_max_energy),
                          shuffle=float(self.pspm_shuffle),
                          shuffle_budget=float(self.pspm_shuffle_budget),
                          max_power=float(self.pspm_max_power))


class Param(NamedTuple):
    """One ROS parameter of the node.

    Attributes:
        name: ROS parameter name (dotted groups).
        field: The :class:`SpgConfig` field it sets.
        description: Text with units, shown by ``ros2 param describe``.
        range: (low, high) for numbers, None otherwise.
    """

    name: str
    field: str
    description: str
    range: tuple[float, float] | None = None


PARAMETERS = (
    Param('robot', 'robot', 'Robot configuration: ' + ', '.join(_ROBOTS)),
    Param('dt', 'dt', 'SPG period dT in [s] (joint-state period of the interface)',
          (1e-4, 0.1)),
    Param('solver', 'solver', 'Cascade solver: ' + ', '.join(SOLVERS) + ' (daqp on a robot; '
          'proxsuite and the nullspace baseline are for comparisons)'),
    Param('rho', 'rho', 'Regularization rho of qdot_v in each level (4.45)', (1e-8, 10.0)),
    Param('torque_limits', 'torque_limits',
          'Implicit top-level joint torque limit task |K (q_v - q)| <= tau_max (4.3)'),
    Param('velocity_box', 'velocity_box',
          "Bound qdot_v by the robot's joint velocity and acceleration limits (4.31-4.33); "
          'false: by the position limits only, as the Ch. 3 nullspace mapping (Alg. C.1/C.2)'),
    Param('pspm.enabled', 'pspm', 'Passive set-point modulation (energy tanks, Sec. 4.2)'),
    Param('pspm.initial_energy', 'pspm_initial_energy', 'Initial tank energy E_r,init in [J]',
          (0.0, 1e4)),
    Param('pspm.max_energy', 'pspm_max_energy', 'Tank ceiling E_r,max in [J]', (0.0, 1e4)),
    Param('pspm.shuffle', 'pspm_shuffle', 'Energy shuffled into each tank per tick in [J]',
          (0.0, 1e3)),
    Param('pspm.shuffle_budget', 'pspm_shuffle_budget',
          'Total shuffled energy per joint b^2 in [J]', (0.0, 1e6)),
    Param('pspm.max_power', 'pspm_max_power',
          "Ceiling of the energy tanks' refill rate in [W] a task stack may ask for with "
          'power_budget (set by a safety engineer; 0: strictly passive)', (0.0, 1e4)),
    Param('impedance.stiffness', 'stiffness',
          "Joint stiffness K of the robot's impedance controller in [Nm/rad], per joint or one "
          "for all (default: the robot configuration's)"),
    Param('impedance.damping', 'damping',
          "Joint damping D of the robot's impedance controller in [Nms/rad], per joint or one "
          "for all (default: the robot configuration's)"),
    Param('watchdog.timeout', 'watchdog_timeout',
          'No joint state for longer than this [s] stops commanding (0: off)', (0.0, 60.0)),
    Param('status.decimation', 'status_decimation', 'Publish spg/status every N-th tick',
          (1, 1_000_000)),
    Param('diagnostics.period', 'diagnostics_period', 'Period of spg/diagnostics in [s]',
          (0.01, 3600.0)),
    Param('task_stack_file', 'task_stack_file',
          "Task-stack file (YAML/JSON) to run from the start ('': wait for spg/task_stack)"),
    Param('topics.joint_states', 'joint_states_topic', 'Input sensor_msgs/JointState topic'),
    Param('topics.command', 'command_topic', 'Output command sensor_msgs/JointState topic'),
    Param('topics.task_stack', 'task_stack_topic', 'Input task-stack std_msgs/String (latched)'),
    Param('topics.status', 'status_topic', 'Output status std_msgs/String (JSON)'),
    Param('topics.diagnostics', 'diagnostics_topic',
          'Output diagnostic_msgs/DiagnosticArray topic'),
    Param('enable', 'enable', 'Command the robot (live; also the latched spg/enable Bool '
          'topic). Off: nothing is published (or the measured q, see command.'
          'hold_when_disabled); on: restart from the measured q'),
    Param('command.hold_when_disabled', 'hold_when_disabled',
          'While disabled, command the measured q'),
    Param('command.interface', 'command_interface',
          'joint_state (sensor_msgs/JointState), float64_multi_array (ros2_control '
          'JointGroupPositionController) or joint_trajectory (one point at dT)'),
    Param('command.joints', 'command_joints',
          "Joint order of the command (ros2_control's 'joints'; default: the robot's)"),
    Param('tick', 'tick', 'joint_states (one tick per joint state) or timer (a tick every dt '
          'with the latest joint state; a state older than watchdog.timeout stops commanding)'),
    Param('hot_path', 'hot_path', 'rclpy: wait_set (joint states taken by a dedicated loop, '
          'the rest on the executor) or executor (every callback from the executor)'),
    Param('markers.rate', 'markers_rate', 'Rate of spg/markers (each Cartesian task target, '
          'visualization_msgs/MarkerArray) in [Hz], at most 30 (0: off)', (0.0, 30.0)),
    Param('markers.frame', 'markers_frame',
          "Frame id of spg/markers: the robot's base frame in your tf tree"),
)
TICKS = ('joint_states', 'timer')

_DEFAULTS: dict[str, Any] = {f.name: f.default for f in fields(SpgConfig)}  # field -> default
_BY_NAME = {p.name: p for p in PARAMETERS}
# Parameters a ROS node may carry without us declaring them.
_FOREIGN_OK = ('use_sim_time', 'qos_overrides.')


def config_from_parameters(values: Mapping[str, Any]) -> 'SpgConfig':
    """Build an :class:`SpgConfig` from ``{ROS parameter name: value}`` (missing: default).

    Raises:
        ParameterError: An unknown name (with a suggestion), a bad type or range.
    """
    kwargs = {}
    for name, value in values.items():
        if name not in _BY_NAME:
            raise ParameterError(f"unknown spg_node parameter '{name}'"
                                 f'{did_you_mean(name, _BY_NAME)}; valid: '
                                 f"{', '.join(_BY_NAME)}")
        field = _BY_NAME[name].field
        if isinstance(_DEFAULTS[field], float) and type(value) is int:
            value = float(value)
        elif isinstance(_DEFAULTS[field], tuple) and not isinstance(value, (list, tuple)):
            value = (value,)  # per-joint values: one number for all
        kwargs[field] = value
    return SpgConfig(**kwargs)


def _descriptor(ros, p, default):
    desc = ros.ParameterDescriptor(description=p.description)
    if p.range is not None:
        if isinstance(default, int) and not isinstance(default, bool):
            desc.integer_range = [ros.IntegerRange(from_value=int(p.range[0]),
                                                   to_value=int(p.range[1]), step=0)]
        else:
            desc.floating_point_range = [ros.FloatingPointRange(
                from_value=float(p.range[0]), to_value=float(p.range[1]), step=0.0)]
    return desc


def _check_value(p: Param, value: Any) -> None:  # value: a ROS parameter's
    """Raise ParameterError unless ``value`` has the type and range of parameter ``p``."""
    default = _DEFAULTS[p.field]
    if type(value) is not type(default) and not (
            isinstance(default, float) and type(value) is int):
        raise ParameterError(f"parameter '{p.name}': {value!r} is a "
                             f'{type(value).__name__}, expected a '
                             f'{type(default).__name__} ({p.description})')
    if p.field == 'command_joints':
        if not all(isinstance(v, str) and v for v in value):
            raise ParameterError(f"parameter '{p.name}': {value!r} must be a list of "
                                 f'joint names ({p.description})')
    elif isinstance(default, tuple):
        if not all(type(v) in (int, float) and math.isfinite(v) for v in value):
            raise ParameterError(f"parameter '{p.name}': {value!r} must be a list of "
                                 f'finite numbers ({p.description})')
    elif p.range is not None and not (p.range[0] <= value <= p.range[1]):
        raise ParameterError(f"parameter '{p.name}': {value!r} is outside "
                             f'[{p.range[0]}, {p.range[1]}] ({p.description})')


def declare_parameters(node: RosNode) -> 'SpgConfig':
    """Declare every parameter of :data:`PARAMETERS` on ``node``; return the SpgConfig.

    Each parameter is declared once, with its description and range; the value comes from
    the command line or params file when given, else the :class:`SpgConfig` default.
    A value the node does not know (a typo in the YAML) is an error, not silently ignored.

    Raises:
        ParameterError: Unknown name, wrong type or out of range (backend errors of rclpy
            are re-raised as ParameterError with their message).
    """
    from ifc_spg import ros  # imports rclpy: only where a node is given
    from ifc_spg.ros.parameters import declare_checked, overrides

    values: dict[str, Any] = {}  # SpgConfig field -> value
    gains = None
    for p in PARAMETERS:
        default = _DEFAULTS[p.field]
        if isinstance(default, tuple):  # per joint: declared with the robot's own values
            gains = gains or robot_gains(values['robot'])
            default = gains[p.field]
        values[p.name] = declare_checked(node, p.name, default, _descriptor(ros, p, default))
        if isinstance(_DEFAULTS[p.field], tuple) and list(values[p.name]) == default:
            values[p.name] = ()  # not overridden: the robot configuration's own
    unknown = [name for name in overrides(node) if name not in _BY_NAME and
               not any(name == f or name.startswith(f) for f in _FOREIGN_OK)]
    if unknown:
        raise ParameterError(f"unknown spg_node parameter '{unknown[0]}'"
                             f'{did_you_mean(unknown[0], _BY_NAME)}; valid: '
                             f"{', '.join(_BY_NAME)}")
    return config_from_parameters(values)


def config_file(robot: str) -> str:
    """Path of ``config/<robot>.yaml``: the source tree's, else the installed share dir.

    Raises:
        ParameterError: No such file (names the places searched).
    """
    here = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    candidates = [os.path.join(here, 'config', f'{robot}.yaml'),
                  os.path.join(sys.prefix, 'share', 'ifc_spg', 'config', f'{robot}.yaml')]
    for path in candidates:
        if os.path.isfile(path):
            return path
    raise ParameterError(f"no parameter file for robot '{robot}'; looked in "
                         f"{', '.join(candidates)}")
