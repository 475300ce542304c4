"""Report Ch. 6 (Vukcevic 2018): the 1-DoF arm with static friction (no simulation).

Evaluates :func:`ifc_spg.dynamics.scenarios.report_problems`; run by
:mod:`experiments.reproduce`.
"""

import numpy as np

from experiments.harness import Check, Experiment

__all__ = ['DIRECT', 'REPORT_6']


def _report_6(out_dir, quick, figures=True):
    """Report Ch. 6 (Vukcevic 2018): the 1-DoF arm with static friction.

    Both inertia readings (the arm as described: COM 0.5 m, I = 0.25 kg m^2; the KDL reading:
    COM 1.5 m, I = 2.25 kg m^2, an inference about the report's code).
    """
    from ifc_spg.dynamics.scenarios import report_problems

    out = {}
    for key, impl in (('described', False), ('kdl', True)):
        row = {}
        for k, prob in enumerate(report_problems(implemented=impl), start=1):
            r = prob.friction_solver().solve(prob.q, prob.qd, prob.tau, **prob.kwargs)
            row[f's{k}_mu'] = float(np.asarray(r.mu)[0])
            row[f's{k}_qdd'] = float(np.asarray(r.qdd)[0])
            row[f's{k}_stick'] = bool(np.asarray(r.stick)[0])
        row['inertia_kg_m2'] = 0.25 if not impl else 2.25
        out[key] = row
    d, kd = out['described'], out['kdl']
    txt = (f"arm as described (COM 0.5 m, I = 0.25 kg m^2): scenario 1 mu* = {d['s1_mu']:.2f} "
           f"Nm, qdd = {d['s1_qdd']:.3g}; scenario 2 mu* = {d['s2_mu']:.2f} Nm, qdd = "
           f"{d['s2_qdd']:.3f} rad/s^2. KDL reading (COM 1.5 m, I = 2.25 kg m^2; INFERENCE): "
           f"scenario 1 mu* = {kd['s1_mu']:.2f} Nm, qdd = {kd['s1_qdd']:.3g}; scenario 2 mu* = "
           f"{kd['s2_mu']:.2f} Nm, qdd = {kd['s2_qdd']:.3f} rad/s^2. Report: 5 Nm / 0; 10 Nm / "
           '-0.44 rad/s^2')
    return Check(out, txt)


REPORT_6 = Experiment('report_6', 'Report Ch. 6', '1-DoF arm with static friction (breakaway '
                      '10 Nm): -5 N sticks (mu* = 5 Nm, qdd = 0), -11 N slips (mu* = 10 Nm, '
                      'qdd = -0.44 rad/s^2)', (), None)
#: Experiment name -> ``(out_dir, quick, figures) -> Check``.
DIRECT = {REPORT_6.name: _report_6}
