"""Constrained manipulation of unknown mechanisms (thesis Ch. 5, docs/SPEC.md §7).

- :class:`DirectionEstimator`: first-order constraint estimator (5.4/5.5),
- :class:`CartesianAdmittanceStrategy` (5.3), :class:`JointComplianceStrategy`
  (5.7-5.11): stand-alone set-point generators ``step(q, qdot, t) -> q_v``,
- :func:`build_tasks`: the task-specification strategy (5.5, Table 5.1) as tasks for the
  :class:`~ifc_spg.spg.SetPointGenerator` (what a ``constrained_manipulation`` entry of a
  task stack expands to),
- :mod:`~ifc_spg.constrained.metrics`: |f_perp|, error angle, travel, time to open,
- :mod:`~ifc_spg.offline.constrained` / :mod:`~ifc_spg.offline.constrained_evaluate`: lockstep runs
  in the MuJoCo scenes and the thesis comparison.
"""

from ifc_spg.constrained.admittance_strategy import CartesianAdmittanceStrategy
from ifc_spg.constrained.direction_estimator import DirectionEstimator, FixedDirection
from ifc_spg.constrained.joint_compliance_strategy import JointComplianceStrategy
from ifc_spg.constrained.params import (
    ORIENTATIONS,
    STRATEGIES,
    EstimatorParams,
    StrategyParams,
    load_params,
    params_from_dict,
)
from ifc_spg.constrained.task_specification import (
    AxisAlignTask,
    ConstrainedWrenchTask,
    build_tasks,
)

__all__ = [
    'ORIENTATIONS',
    'STRATEGIES',
    'AxisAlignTask',
    'CartesianAdmittanceStrategy',
    'ConstrainedWrenchTask',
    'DirectionEstimator',
    'EstimatorParams',
    'FixedDirection',
    'JointComplianceStrategy',
    'StrategyParams',
    'build_tasks',
    'load_params',
    'params_from_dict',
]
