"""Problems for the dynamics CLI: the report's Ch. 6 scenarios and user problem files.

A problem file (YAML) names a model and a state::

    model: arm.urdf            # URDF (.urdf) or MJCF (.xml, .mjcf); relative to this file
    tip_frame: tool            # optional: frame on the last segment where A_N acts
    q: [0.0, 0.5, -0.3]        # [rad] / [m], pinocchio configuration (nq entries)
    qd: [0.0, 0.0, 0.1]        # [rad/s], default zeros
    tau: [0.0, 0.0, 0.0]       # feed-forward [Nm], default zeros
    gravity: [0, 0, -9.81]     # [m/s^2] (base acceleration -g); or
    # base_acceleration: [0, 0, 9.81, 0, 0, 0]
    external_wrenches:         # wrench at a frame origin, base axes, acting on the robot
      - {frame: tool, force: [0, -5, 0], torque: [0, 0, 0]}
    constraints:               # optional: A_N^T Xdd_N = b_N on the last segment
      A_N: [[1, 0, 0, 0, 0, 0]]   # list of m unit wrench columns [fx fy fz mx my mz]
      b_N: [0.0]
    friction:                  # optional: static friction at joints with |qd| <= eps
      breakaway: 10.0          # [Nm], scalar or one per joint
      eps: 1.0e-6
"""

from dataclasses import dataclass, field
import os

import numpy as np
import pinocchio as pin
import yaml

from ifc_spg.dynamics.models import one_dof_arm
from ifc_spg.dynamics.static_friction import StaticFrictionSolver
from ifc_spg.dynamics.vereshchagin import VereshchaginSolver
from ifc_spg.errors import IfcSpgError, ModelError, ParameterError, UnknownFrame, did_you_mean

__all__ = ['Problem', 'load_problem', 'report_problems', 'external_joint_torques']

_KEYS = ('model', 'tip_frame', 'q', 'qd', 'tau', 'gravity', 'base_acceleration',
         'external_wrenches', 'constraints', 'friction', 'name')


@dataclass
class Problem:
    """A solver input: model, state, loads, constraints and friction.

    Attributes:
        name: Label for printing and plot file names.
        model: pinocchio Model.
        tip_frame: Frame where A_N acts (None: last joint frame).
        q, qd, tau: State and feed-forward torques.
        kwargs: ``base_acceleration``, ``external_wrenches``, ``A_N``, ``b_N``.
        breakaway: Breakaway torques (None: no friction).
        eps: Rest threshold [rad/s].
        expected: Free text with the report's expected outcome (scenarios only).
    """

    name: str
    model: object
    tip_frame: object
    q: np.ndarray
    qd: np.ndarray
    tau: np.ndarray
    kwargs: dict = field(default_factory=dict)
    breakaway: object = None
    eps: float = 1e-6
    expected: str = ''

    def solver(self):
        """Return a :class:`VereshchaginSolver` for this problem."""
        return VereshchaginSolver(self.model, tip_frame=self.tip_frame)

    def friction_solver(self, qp_solver='proxsuite'):
        """Return a :class:`StaticFrictionSolver` (breakaway 0 if the problem has none)."""
        f = 0.0 if self.breakaway is None else self.breakaway
        return StaticFrictionSolver(self.solver(), f, eps=self.eps, qp_solver=qp_solver)


def external_joint_torques(model, q, external_wrenches):
    """Joint torques J_iᵀ F_i of the external wrenches (solver convention) [Nm]."""
    if external_wrenches is None:
        return np.zeros(model.nv)
    m = model.copy()
    m.gravity = pin.Motion.Zero()
    d = m.createData()
    pin.forwardKinematics(m, d, q)
    fl = pin.StdVec_Force()
    fl.append(pin.Force.Zero())
    for i, w in enumerate(np.asarray(external_wrenches, dtype=float)):
        R = d.oMi[i + 1].rotation
        fl.append(pin.Force(R.T @ w[:3], R.T @ w[3:]))
    return -pin.rnea(m, d, q, np.zeros(m.nv), np.zeros(m.nv), fl)


def report_problems(*, implemented=False):
    """Return the report's Ch. 6 scenarios as problems.

    1-DoF arm, 1 kg, 1 m, COM at 0.5 m, no gravity, breakaway ±10 Nm, tip force −5 N
    (scenario 1) and −11 N (scenario 2).

    Args:
        implemented: Build the arm as the report's KDL code did: KDL expresses segment
            inertia in the segment's *tip* frame, so ``Inertia(1, cog=(0.5, 0, 0))`` on a
            1 m segment puts the COM 1.5 m from the joint (I = 2.25 kg m^2), which is
            what gives the report's q̈ = −0.44 rad/s^2. Default: the arm as described
            (point mass at 0.5 m, I = 0.25 kg m^2).
    """
    com = 1.5 if implemented else 0.5
    model = one_dof_arm(mass=1.0, length=1.0, com=com)
    tag = ' (as implemented in KDL: COM at 1.5 m)' if implemented else ''
    out = []
    for k, (fy, expected) in enumerate(((-5.0, 'mu* = 5 Nm, qdd = 0 (sticks)'),
                                        (-11.0, '|mu*| = 10 Nm, resulting torque -1 Nm, '
                                         'qdd = -1 Nm / I (slips)')), start=1):
        wrench = np.array([[0.0, fy, 0.0, 0.0, 0.0, 1.0 * fy]])   # tip force moved to joint
        out.append(Problem(
            name=f'scenario{k}{"_kdl" if implemented else ""}', model=model, tip_frame='tip',
            q=np.zeros(1), qd=np.zeros(1), tau=np.zeros(1),
            kwargs={'base_acceleration': np.zeros(6), 'external_wrenches': wrench},
            breakaway=10.0, eps=1e-6,
            expected=f'tip force {fy:g} N{tag}: {expected}'))
    return out


def _vec(doc, key, size, path, default=None):
    if key not in doc or doc[key] is None:
        if default is None:
            raise ParameterError(f"{path}: missing '{key}' (a list of {size} numbers)")
        return np.array(default, dtype=float)
    try:
        a = np.array(doc[key], dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ParameterError(f"{path}: '{key}' must be a list of numbers, got "
                             f'{doc[key]!r}') from None
    if size is not None and a.size == 1 and size > 1 and key == 'breakaway':
        a = np.full(size, a[0])
    if size is not None and a.shape != (size,):
        raise ParameterError(f"{path}: '{key}' must have {size} entries, got {a.size}")
    return a


def load_problem(path):
    """Read a problem file (format in the module docstring).

    Args:
        path: The problem file (YAML).

    Raises:
        ParameterError: Missing/ill-typed fields (the message names the file and field).
        ModelError: The model file is missing or cannot be parsed.
        UnknownFrame: A frame name is not in the model.
    """
    doc = _read_doc(path)
    model = _load_model(path, doc)
    n = model.nv
    q = _vec(doc, 'q', model.nq, path, default=pin.neutral(model))
    qd = _vec(doc, 'qd', n, path, default=np.zeros(n))
    tau = _vec(doc, 'tau', n, path, default=np.zeros(n))
    kwargs = {}
    if 'base_acceleration' in doc and 'gravity' in doc:
        raise ParameterError(f"{path}: give either 'gravity' or 'base_acceleration', not both")
    if 'base_acceleration' in doc:
        kwargs['base_acceleration'] = _vec(doc, 'base_acceleration', 6, path)
    elif 'gravity' in doc:
        g = _vec(doc, 'gravity', 3, path)
        kwargs['base_acceleration'] = np.concatenate((-g, np.zeros(3)))
    if doc.get('external_wrenches'):
        kwargs['external_wrenches'] = _wrenches(model, q, doc['external_wrenches'], path)
    if doc.get('constraints'):
        kwargs['A_N'], kwargs['b_N'] = _constraints(doc['constraints'], path)
    breakaway, eps = None, 1e-6
    fr = doc.get('friction')
    if fr:
        if not isinstance(fr, dict):
            raise ParameterError(f"{path}: 'friction' must be a mapping with 'breakaway'")
        breakaway = _vec(fr, 'breakaway', n, path)
        eps = float(fr.get('eps', 1e-6))
    prob = Problem(name=str(doc.get('name', os.path.splitext(os.path.basename(path))[0])),
                   model=model, tip_frame=doc.get('tip_frame'), q=q, qd=qd, tau=tau,
                   kwargs=kwargs, breakaway=breakaway, eps=eps)
    try:
        prob.solver()
    except IfcSpgError as exc:
        raise type(exc)(f'{path}: {exc}') from None
    return prob


def _read_doc(path):
    """The problem file's mapping, its keys checked (ParameterError naming the file)."""
    if not os.path.isfile(path):
        raise ParameterError(f"problem file '{path}' does not exist")
    try:
        with open(path, encoding='utf-8') as fh:
            doc = yaml.safe_load(fh)
    except yaml.YAMLError as exc:
        raise ParameterError(f"problem file '{path}' is not valid YAML: {exc}") from None
    if not isinstance(doc, dict):
        raise ParameterError(f"problem file '{path}' must be a YAML mapping with keys "
                             f"{', '.join(_KEYS)}")
    for key in doc:
        if key not in _KEYS:
            raise ParameterError(f"{path}: unknown key '{key}'{did_you_mean(key, _KEYS)}; "
                                 f"valid keys: {', '.join(_KEYS)}")
    if 'model' not in doc:
        raise ParameterError(f"{path}: missing 'model' (path of a URDF or MJCF file)")
    return doc


def _load_model(path, doc):
    """The pinocchio model of ``doc['model']`` (relative to the problem file's folder)."""
    mpath = os.path.join(os.path.dirname(os.path.abspath(path)), str(doc['model']))
    if not os.path.isfile(mpath):
        raise ModelError(f"{path}: model file '{mpath}' does not exist")
    ext = os.path.splitext(mpath)[1].lower()
    try:
        if ext == '.urdf':
            return pin.buildModelFromUrdf(mpath)
        if ext in ('.xml', '.mjcf'):
            return pin.buildModelFromMJCF(mpath)
    except (RuntimeError, ValueError) as exc:
        raise ModelError(f"{path}: could not load model '{mpath}': {exc}") from None
    raise ModelError(f"{path}: model file '{mpath}' must end in .urdf (URDF) or "
                     '.xml / .mjcf (MJCF)')


def _constraints(cons, path):
    """``(A_N (6, m), b_N (m,))`` of the ``constraints`` entry (columns given as rows)."""
    if not isinstance(cons, dict) or 'A_N' not in cons:
        raise ParameterError(f"{path}: 'constraints' needs 'A_N' (list of 6-vectors) and "
                             "'b_N'")
    try:
        A = np.array(cons['A_N'], dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(f'{path}: constraints.A_N must be a list of 6-number '
                             'columns') from None
    if A.ndim == 1:
        A = A[None]
    if A.ndim != 2 or A.shape[1] != 6 or A.shape[0] > 6:
        raise ParameterError(f'{path}: constraints.A_N must be a list of at most 6 '
                             f'columns with 6 numbers each, got shape {A.shape}')
    return A.T, _vec(cons, 'b_N', A.shape[0], path, default=np.zeros(A.shape[0]))


def _wrenches(model, q, items, path):
    """The ``external_wrenches`` entries as per-segment wrenches (n, 6) at the joints."""
    if not isinstance(items, list):
        raise ParameterError(f"{path}: 'external_wrenches' must be a list of "
                             '{frame, force, torque}')
    d = model.createData()
    pin.forwardKinematics(model, d, q)
    pin.updateFramePlacements(model, d)
    W = np.zeros((model.nv, 6))
    names = [f.name for f in model.frames]
    for k, item in enumerate(items):
        if not isinstance(item, dict) or 'frame' not in item:
            raise ParameterError(f'{path}: external_wrenches[{k}] needs a frame, force and '
                                 'torque')
        name = str(item['frame'])
        if not model.existFrame(name):
            raise UnknownFrame(f"{path}: external_wrenches[{k}].frame '{name}' is not in the "
                               f'model{did_you_mean(name, names)}')
        fid = model.getFrameId(name)
        j = model.frames[fid].parentJoint
        if j == 0:
            raise ParameterError(f"{path}: external_wrenches[{k}].frame '{name}' is on the "
                                 'fixed base; a wrench there does not move the robot')
        f = _vec(item, 'force', 3, path, default=np.zeros(3))
        t = _vec(item, 'torque', 3, path, default=np.zeros(3))
        r = d.oMf[fid].translation - d.oMi[j].translation
        W[j - 1, :3] += f
        W[j - 1, 3:] += t + np.cross(r, f)
    return W
