"""Robot model: pinocchio kinematics/dynamics plus the IFC parameters the SPG must know.

A :class:`RobotModel` is immutable and shared: the pinocchio ``Model`` is never modified
after construction, and every solver creates its own ``Data`` with :meth:`create_data`
(docs/STYLE.md rule 6).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
import os
from typing import Any

import numpy as np
import pinocchio as pin

from ifc_spg.errors import ModelError, ParameterError, UnknownFrame, UnknownJoint, did_you_mean
from ifc_spg.model import registry
from ifc_spg.model.ifc import CARTESIAN_ADMITTANCE, JOINT_IMPEDANCE, CartesianAdmittance

__all__ = ['CartesianAdmittance', 'RobotModel', 'JOINT_IMPEDANCE', 'CARTESIAN_ADMITTANCE',
           'robot_gains']


def _readonly(x: Any, n: int, what: str) -> np.ndarray:
    a = np.array(np.broadcast_to(np.asarray(x, dtype=float), (n,)), dtype=float)
    if not np.all(np.isfinite(a)):
        raise ModelError(f'{what} must be finite, got {a.tolist()}')
    a.setflags(write=False)
    return a


class RobotModel:
    """A fixed-base serial or tree robot with revolute/prismatic joints and its IFC parameters.

    Args:
        model: pinocchio model (nq == nv, 1-DoF joints only).
        name: Configuration name, used in error messages.
        frames: Chain id -> pinocchio frame name (e.g. ``{'tool': 'tool_frame'}``).
        stiffness: Joint stiffness K in [Nm/rad] (scalar or per joint).
        damping: Joint damping D in [Nms/rad] (scalar or per joint).
        q_min, q_max: Joint position limits in [rad] (default: from the model file).
        v_max: Joint velocity limit in [rad/s] (default: from the model file).
        a_max: Joint acceleration limit in [rad/s^2].
        tau_max: Joint torque limit in [Nm] (default: from the model file).
        stiff_joints: Names of position-controlled joints (no compliance, e.g. iCub wrists).
        q_home: Home configuration in [rad] (default: zeros clipped into the limits).
        ifc: ``'joint_impedance'`` or ``'cartesian_admittance'``.
        admittance: Chain id -> :class:`CartesianAdmittance` (for ``cartesian_admittance``).
        model_file: Path of the file the model was loaded from (shared with the simulator).
        spec_builder: Callable returning a fresh ``mujoco.MjSpec`` of this robot for the
            simulator (default: ``model_file`` loaded as is), see
            ``sim_bridge.models.robot_mjcf_spec``.

    Attributes:
        compliant_stiffness: K with zeros at stiff (position-controlled) joints [Nm/rad].
        compliant_damping: D with zeros at stiff joints [Nms/rad].
    """

    def __init__(self, model: pin.Model, *, name: str, frames: Mapping[str, str],
                 stiffness: Any, damping: Any, q_min: Any = None, q_max: Any = None,
                 v_max: Any = None, a_max: Any = 10.0, tau_max: Any = None,
                 stiff_joints: Sequence[str] = (), q_home: Any = None,
                 ifc: str = JOINT_IMPEDANCE,
                 admittance: Mapping[str, CartesianAdmittance] | None = None,
                 model_file: str | None = None,
                 spec_builder: Callable[[], Any] | None = None) -> None:
        if model.nq != model.nv:
            raise ModelError(f"model '{name}': only 1-DoF revolute/prismatic joints are "
                             f'supported (nq={model.nq} != nv={model.nv}); replace continuous '
                             'joints by revolute joints with limits')
        self.model = model
        self.name = str(name)
        n = model.nv
        self.n = n
        self.joint_names = tuple(model.names[1:])
        self._joint_index = {j: i for i, j in enumerate(self.joint_names)}
        self.q_min = _readonly(model.lowerPositionLimit if q_min is None else q_min, n, 'q_min')
        self.q_max = _readonly(model.upperPositionLimit if q_max is None else q_max, n, 'q_max')
        if np.any(self.q_min >= self.q_max):
            raise ModelError(f"model '{name}': q_min must be < q_max for every joint "
                             f'(q_min={self.q_min.tolist()}, q_max={self.q_max.tolist()})')
        self._set_limits_and_gains(model, v_max, a_max, tau_max, stiffness, damping)
        mask = np.zeros(n, dtype=bool)
        for j in stiff_joints:
            mask[self.joint_index(j)] = True
        mask.setflags(write=False)
        self.stiff_mask = mask
        self.compliant_columns = _readonly((~mask).astype(float), n, 'compliant_columns')
        self.compliant_stiffness = _readonly(np.where(mask, 0.0, self.stiffness), n,
                                             'stiffness')
        self.compliant_damping = _readonly(np.where(mask, 0.0, self.damping), n, 'damping')
        self._set_frames(frames)
        if q_home is None:
            q_home = np.clip(np.zeros(n), self.q_min, self.q_max)
        self.q_home = _readonly(q_home, n, 'q_home')
        self._set_ifc(ifc, admittance)
        self.model_file = model_file
        self.spec_builder = spec_builder
        self._stiff_joints = tuple(stiff_joints)

    def _set_limits_and_gains(self, model, v_max, a_max, tau_max, stiffness, damping):
        n, name = self.n, self.name
        self.v_max = _readonly(model.velocityLimit if v_max is None else v_max, n, 'v_max')
        self.a_max = _readonly(a_max, n, 'a_max')
        self.tau_max = _readonly(model.effortLimit if tau_max is None else tau_max, n, 'tau_max')
        for what, arr in (('v_max', self.v_max), ('a_max', self.a_max), ('tau_max', self.tau_max)):
            if np.any(arr <= 0):
                raise ModelError(f"model '{name}': {what} must be > 0, got {arr.tolist()}")
        self.stiffness = _readonly(stiffness, n, 'stiffness')
        self.damping = _readonly(damping, n, 'damping')
        if np.any(self.stiffness <= 0) or np.any(self.damping < 0):
            raise ModelError(f"model '{name}': stiffness must be > 0 and damping >= 0 "
                             f'(K={self.stiffness.tolist()}, D={self.damping.tolist()})')

    def _set_frames(self, frames):
        model, name = self.model, self.name
        self.frames = dict(frames)
        self._frame_ids = {}
        for chain, fname in self.frames.items():
            if not model.existFrame(fname):
                raise UnknownFrame(f"model '{name}': chain '{chain}' names frame '{fname}' which "
                                   'is not in the model file' + did_you_mean(
                                       fname, [f.name for f in model.frames]))
            self._frame_ids[chain] = model.getFrameId(fname)

    def _set_ifc(self, ifc, admittance):
        name = self.name
        if ifc not in (JOINT_IMPEDANCE, CARTESIAN_ADMITTANCE):
            raise ModelError(f"model '{name}': ifc must be '{JOINT_IMPEDANCE}' or "
                             f"'{CARTESIAN_ADMITTANCE}', got '{ifc}'")
        self.ifc = ifc
        self.admittance = dict(admittance or {})
        if ifc == CARTESIAN_ADMITTANCE:
            for chain in self.admittance:
                self.frame_id(chain)
            if not self.admittance:
                raise ModelError(f"model '{name}': cartesian_admittance needs admittance "
                                 'parameters for at least one chain')

    # -- construction --------------------------------------------------------------------
    @classmethod
    def from_urdf(cls, path: str | os.PathLike[str], *, joints: Sequence[str] | None = None,
                  q_lock: Mapping[str, float] | None = None,
                  **ifc_params: Any) -> RobotModel:
        """Load a URDF; keep only ``joints`` (others locked at ``q_lock``, default 0)."""
        if not os.path.isfile(path):
            raise ModelError(f"URDF file '{path}' does not exist")
        try:
            model = pin.buildModelFromUrdf(str(path))
        except (RuntimeError, ValueError) as exc:
            raise ModelError(f"could not load URDF '{path}': {exc}") from exc
        model = _reduce(model, joints, q_lock)
        return cls(model, model_file=str(path), **ifc_params)

    @classmethod
    def from_mjcf(cls, path: str | os.PathLike[str], *, joints: Sequence[str] | None = None,
                  q_lock: Mapping[str, float] | None = None,
                  **ifc_params: Any) -> RobotModel:
        """Load an MJCF file; keep only ``joints`` (others locked at ``q_lock``, default 0)."""
        if not os.path.isfile(path):
            raise ModelError(f"MJCF file '{path}' does not exist")
        try:
            model = pin.buildModelFromMJCF(str(path))
        except (RuntimeError, ValueError) as exc:
            raise ModelError(f"could not load MJCF '{path}': {exc}") from exc
        model = _reduce(model, joints, q_lock)
        return cls(model, model_file=str(path), **ifc_params)

    @classmethod
    def from_config(cls, name: str) -> RobotModel:
        """Build a named configuration: ``lbr4``, ``lbr_iiwa14``, ``icub_upper_body``, ..."""
        return cls(**registry.robot_arguments(name))

    def with_gains(self, stiffness: Any = None, damping: Any = None, *,
                   where: str = '') -> RobotModel:
        """This robot with other joint-impedance gains (the pinocchio model is shared).

        Args:
            stiffness: Joint stiffness K [Nm/rad], scalar or per joint (None: keep).
            damping: Joint damping D [Nms/rad], scalar or per joint (None: keep).
            where: Prefix of error messages naming the source (e.g. ``"scenario 'x': sim."``).

        Returns:
            ``self`` when neither is given, else a new :class:`RobotModel` built (and
            validated) by the constructor.

        Raises:
            ParameterError: A value that is not a finite number (K > 0, D >= 0) or a wrong
                count; the message names the joints.
        """
        if stiffness is None and damping is None:
            return self
        gains: dict[str, np.ndarray] = {}
        for key, raw, old in (('stiffness', stiffness, self.stiffness),
                              ('damping', damping, self.damping)):
            if raw is None:
                gains[key] = old
                continue
            try:
                value = np.asarray(raw, dtype=float).reshape(-1)
            except (TypeError, ValueError):
                value = np.array([np.nan])
            if value.size == 1:
                value = np.full(self.n, value[0])
            if value.shape != (self.n,) or not np.all(np.isfinite(value)) or np.any(
                    value < 0) or (key == 'stiffness' and np.any(value <= 0)):
                raise ParameterError(f'{where}{key} must be '
                                     f'{"> 0" if key == "stiffness" else ">= 0"} '
                                     f'(scalar or {self.n} values for '
                                     f"{', '.join(self.joint_names)}), got {raw!r}")
            gains[key] = value
        return RobotModel(
            self.model, name=self.name, frames=self.frames, q_min=self.q_min, q_max=self.q_max,
            v_max=self.v_max, a_max=self.a_max, tau_max=self.tau_max,
            stiff_joints=self._stiff_joints, q_home=self.q_home, ifc=self.ifc,
            admittance=self.admittance, model_file=self.model_file,
            spec_builder=self.spec_builder, **gains)

    # -- lookups -------------------------------------------------------------------------
    def create_data(self) -> pin.Data:
        """Return a fresh pinocchio ``Data`` owned by the caller."""
        return self.model.createData()

    def frame_id(self, chain: str) -> int:
        """Return the pinocchio frame id of chain id ``chain`` (raises :class:`UnknownFrame`)."""
        try:
            return self._frame_ids[chain]
        except KeyError:
            raise UnknownFrame(
                f"frame '{chain}' not in model '{self.name}'"
                f"{did_you_mean(chain, self._frame_ids)}; available: "
                f"{', '.join(sorted(self._frame_ids)) or '(none)'}") from None

    def joint_index(self, joint: str) -> int:
        """Return the index of joint ``joint`` in q (raises :class:`UnknownJoint`)."""
        try:
            return self._joint_index[joint]
        except KeyError:
            raise UnknownJoint(
                f"joint '{joint}' not in model '{self.name}'"
                f"{did_you_mean(joint, self.joint_names)}; available: "
                f"{', '.join(self.joint_names)}") from None

    @property
    def chains(self) -> tuple[str, ...]:
        """The chain ids (frame names usable in task stacks)."""
        return tuple(self._frame_ids)

    def __repr__(self) -> str:
        return (f'RobotModel({self.name!r}, n={self.n}, ifc={self.ifc!r}, '
                f'chains={list(self._frame_ids)})')


def _reduce(model: pin.Model, joints: Sequence[str] | None,
            q_lock: Mapping[str, float] | None) -> pin.Model:
    if joints is None:
        return model
    names = list(model.names[1:])
    for j in joints:
        if j not in names:
            raise UnknownJoint(f"joint '{j}' not in model{did_you_mean(j, names)}")
    lock = [model.getJointId(j) for j in names if j not in set(joints)]
    q_ref = pin.neutral(model)
    for j, v in (q_lock or {}).items():
        jid = model.getJointId(j)
        q_ref[model.joints[jid].idx_q] = v
    reduced = pin.buildReducedModel(model, lock, q_ref)
    if list(reduced.names[1:]) != list(joints):
        order = list(reduced.names[1:])
        raise ModelError(f'joints must be listed in model order: {order}')
    return reduced


def robot_gains(robot: str) -> dict:
    """``{'stiffness': K, 'damping': D, 'command_joints': names}`` of a robot configuration.

    Lists of floats (and the joint names): the declared defaults of the gain parameters, so
    that ``ros2 param get`` shows what the node computes with (spg_node, sim_bridge).

    Args:
        robot: The robot configuration's name.
    """
    model = RobotModel.from_config(robot)  # an unknown robot: the error names the choices
    out = {key: [float(v) for v in getattr(model, key)] for key in ('stiffness', 'damping')}
    out['command_joints'] = list(model.joint_names)
    return out
