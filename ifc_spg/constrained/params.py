"""Parameters of constrained manipulation (thesis Ch. 5) with the thesis defaults.

The defaults are those of the joint-level experiments (Sec. 5.4.3): 500 Hz, K = 40 Nm/rad,
SMA order N = 500, dead band v_th = 0.01 m/s, exploration rate kappa = 9 N/s and
exploration velocity nu = 0.05 m/s. ``config/constrained_manipulation.yaml`` holds the same
numbers; :func:`load_params` reads it (or any file of that shape) and overrides the
dataclass defaults, so the YAML only overrides (docs/STYLE.md rule 4).
"""

from dataclasses import dataclass, field, fields, replace
import math

import numpy as np

from ifc_spg.errors import ParameterError, did_you_mean

__all__ = [
    'ORIENTATIONS',
    'STRATEGIES',
    'EstimatorParams',
    'StrategyParams',
    'load_params',
    'params_from_dict',
]

#: Orientation regulation modes (Sec. 5.3.3, 5.4.2, 5.5.2).
ORIENTATIONS = ('free', 'fixed', 'align_z', 'release_y')
#: The three strategies (Sec. 5.3, 5.4, 5.5).
STRATEGIES = ('admittance', 'joint_compliance', 'task_specification')


#: Largest SMA order N (samples: 2000 s at 500 Hz, a 24 MB ring buffer); the fuzz of the
#: task-stack language found N = 5e8 allocating 12 GB in the stack's build.
MAX_WINDOW = 1_000_000


@dataclass(frozen=True)
class EstimatorParams:
    """First-order constraint estimator (5.4/5.5).

    Attributes:
        window: SMA order N (samples); the time window is N dt.
        v_threshold: Dead band v_th in [m/s]: slower samples are replaced by w0 d_hat.
        w0: Weight w0 of the last estimate substituted in the dead band in [m/s]
            (default: v_th, i.e. a dead-band sample counts like the slowest valid one).
        initial_direction: Initial direction d_p0 (3,), base frame; normalized on use.
    """

    window: int = 500
    v_threshold: float = 0.01
    w0: float = 0.01
    initial_direction: tuple = (0.0, 0.0, 1.0)

    def __post_init__(self):
        if int(self.window) != self.window or not 1 <= self.window <= MAX_WINDOW:
            raise ParameterError(f'estimator.window (SMA order N) must be an integer in [1, '
                                 f'{MAX_WINDOW}] (the ring buffer holds N samples), got '
                                 f'{self.window!r}')
        for key in ('v_threshold', 'w0'):
            v = getattr(self, key)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ParameterError(f'estimator.{key} must be a finite number >= 0 [m/s], got '
                                     f'{v!r}')
        if self.w0 <= 0:
            raise ParameterError(f'estimator.w0 must be > 0 (5.5), got {self.w0!r}')
        try:
            d = np.asarray(self.initial_direction, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            d = np.zeros(0)
        if d.shape != (3,) or not np.all(np.isfinite(d)) or np.linalg.norm(d) < 1e-9:
            raise ParameterError('estimator.initial_direction must be 3 finite numbers, not all '
                                 f'zero (a direction in the base frame), got '
                                 f'{self.initial_direction!r}')
        object.__setattr__(self, 'initial_direction', tuple(float(x) for x in d))


@dataclass(frozen=True)
class StrategyParams:
    """Parameters shared by the three strategies.

    Attributes:
        dt: Set-point period dT in [s] (500 Hz).
        stiffness: Joint stiffness K in [Nm/rad] of the joint-impedance experiments.
        kappa: Exploration rate kappa (force slope) in [N/s] (joint-level strategies).
        nu: Exploration velocity nu in [m/s] (admittance strategy).
        orientation: 'free', 'fixed', 'align_z' or 'release_y'.
        orientation_gain: k_o in [1/s] of the orientation regulators.
        force_gain: Lambda in [1/s] of the level-1 wrench task (cancels f_perp).
        posture_gain: Gain of the posture level in [1/s] (0 disables the level).
        max_force: Cap of the exploration force along d_hat in [N] (inf: none).
        pspm: Run the task-specification strategy's SPG with the passivity stabilizer.
            Off by default: opening a mechanism is active work (lifting the 1.2 kg drawer
            0.3 m takes 3.5 J) and the default tanks (0.5 J per joint) run dry after a few
            centimetres, after which the exploration level becomes infeasible.
        estimator: The :class:`EstimatorParams`.
    """

    dt: float = 0.002
    stiffness: float = 40.0
    kappa: float = 9.0
    nu: float = 0.05
    orientation: str = 'fixed'
    orientation_gain: float = 2.0
    force_gain: float = 50.0
    posture_gain: float = 1.0
    max_force: float = math.inf
    pspm: bool = False
    estimator: EstimatorParams = field(default_factory=EstimatorParams)

    def __post_init__(self):
        for key in ('dt', 'stiffness', 'kappa', 'nu', 'orientation_gain', 'force_gain',
                    'posture_gain', 'max_force'):
            v = getattr(self, key)
            if not (isinstance(v, (int, float)) and not math.isnan(v) and v >= 0):
                raise ParameterError(f'{key} must be a number >= 0, got {v!r}')
        if not 0 < self.dt <= 1.0:
            raise ParameterError(f'dt must be a period in (0, 1] s, got {self.dt!r}')
        if self.orientation not in ORIENTATIONS:
            raise ParameterError(f"orientation '{self.orientation}' unknown"
                                 f'{did_you_mean(self.orientation, ORIENTATIONS)}; choose one '
                                 f"of {', '.join(ORIENTATIONS)}")
        if not isinstance(self.estimator, EstimatorParams):
            raise ParameterError('estimator must be an EstimatorParams')


def _check_keys(d, allowed, where):
    if not isinstance(d, dict):
        raise ParameterError(f'{where} must be a mapping, got {type(d).__name__}')
    for key in d:
        if key not in allowed:
            raise ParameterError(f"{where}: unknown key '{key}'{did_you_mean(key, allowed)}; "
                                 f"valid keys: {', '.join(allowed)}")


def params_from_dict(d, base=None):
    """Build :class:`StrategyParams` from a (YAML) mapping, overriding ``base``.

    Args:
        d: Mapping with keys of :class:`StrategyParams`; ``estimator`` a mapping with keys of
            :class:`EstimatorParams` (``window``, ``v_threshold``, ``w0``,
            ``initial_direction``).
        base: Parameters to override (default: the thesis defaults).

    Raises:
        ParameterError: An unknown key (named, with the valid ones) or a bad value.
    """
    base = base or StrategyParams()
    names = [f.name for f in fields(StrategyParams)]
    _check_keys(d, names, 'constrained manipulation parameters')
    d = dict(d)
    est = d.pop('estimator', None)
    estimator = base.estimator
    if est is not None:
        _check_keys(est, [f.name for f in fields(EstimatorParams)], 'estimator')
        estimator = replace(estimator, **est)
    if 'max_force' in d and d['max_force'] is None:
        d['max_force'] = math.inf
    return replace(base, estimator=estimator, **d)


def load_params(path):
    """Read parameters from a YAML file (``strategy:`` mapping at the top level)."""
    import yaml
    with open(path, encoding='utf-8') as f:
        doc = yaml.safe_load(f) or {}
    _check_keys(doc, ['strategy', 'scenarios'], str(path))
    return params_from_dict(doc.get('strategy', {}))
