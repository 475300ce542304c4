"""Static friction cross-check with MuJoCo's joint ``frictionloss`` (1-DoF and 3-DoF arms).

MuJoCo solves the same box-constrained dual, but soft: its friction rows carry a
regularizer R_j = (1 − d)/d · A_jj (d = solimp impedance, here 0.9999), i.e. it minimizes
½ μᵀ(G + R)μ + q̈(0)ᵀμ instead of ½ μᵀGμ + q̈(0)ᵀμ. Hence the tolerance: for a strongly
convex box QP the two minimizers differ by ‖Δμ‖ ≤ ‖R μ_mj‖ / λ_min(G) (add the two
variational inequalities), so ‖Δq̈‖ = ‖G Δμ‖ ≤ cond(G) ‖R μ_mj‖, computed from MuJoCo's own
``efc_R`` and ``efc_force`` for each state (typically 1e-4 of the friction acceleration).
With R added to our QP the two must agree to solver precision.
"""

import os
import tempfile

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from ifc_spg.dynamics import StaticFrictionSolver, VereshchaginSolver

_OPTIONS = ('<option gravity="0 0 -9.81" timestep="0.001" solver="Newton" tolerance="1e-15" '
            'iterations="500" ls_tolerance="1e-12"/>'
            '<default><joint armature="0.05" solimpfriction="0.9999 0.9999 0.001 0.5 2"/>'
            '<geom contype="0" conaffinity="0"/></default>')

ARM1 = ('<mujoco model="arm1">' + _OPTIONS + '<worldbody><body name="l1">'
        '<joint name="j1" type="hinge" axis="0 0 1" frictionloss="10"/>'
        '<inertial pos="0.5 0 0" mass="1" diaginertia="1e-4 1e-4 1e-4"/>'
        '</body></worldbody></mujoco>')

ARM3 = ('<mujoco model="arm3">' + _OPTIONS + '<worldbody><body name="l1">'
        '<joint name="j1" type="hinge" axis="0 0 1" frictionloss="3"/>'
        '<inertial pos="0.2 0 0.05" mass="2" diaginertia="0.01 0.03 0.03"/>'
        '<body name="l2" pos="0.4 0 0.1">'
        '<joint name="j2" type="hinge" axis="0 1 0" frictionloss="8"/>'
        '<inertial pos="0.15 0 0" mass="1.5" diaginertia="0.004 0.02 0.02"/>'
        '<body name="l3" pos="0.3 0 0" euler="0.3 0 0">'
        '<joint name="j3" type="hinge" axis="0 1 0" frictionloss="1.5"/>'
        '<inertial pos="0.1 0.01 0" mass="0.8" diaginertia="0.002 0.005 0.005"/>'
        '</body></body></body></worldbody></mujoco>')


def _models(xml):
    mj = mujoco.MjModel.from_xml_string(xml)
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, 'arm.xml')
        with open(path, 'w', encoding='utf-8') as fh:
            fh.write(xml)
        model = pin.buildModelFromMJCF(path)
    model.armature[:] = mj.dof_armature
    return mj, model


@pytest.mark.parametrize('xml,draws,scale', [(ARM1, 12, 15.0), (ARM3, 25, 12.0)])
def test_frictionloss_cross_check(xml, draws, scale):
    mj, model = _models(xml)
    data = mujoco.MjData(mj)
    n = mj.nv
    f = mj.dof_frictionloss.copy()
    fs = StaticFrictionSolver(VereshchaginSolver(model), f)
    rng = np.random.default_rng(40 + n)
    seen = {'stick': 0, 'slip': 0}
    compared = 0
    for _ in range(draws):
        q = rng.uniform(-2, 2, n)
        tau = rng.normal(size=n) * scale
        data.qpos[:] = q
        data.qvel[:] = 0.0
        data.qfrc_applied[:] = tau
        mujoco.mj_forward(mj, data)
        fric = data.efc_type == mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF
        assert fric.sum() == n
        mu_mj = data.efc_force[fric].copy()          # friction torque acting on the joints
        R = data.efc_R[fric].copy()
        qdd_mj = data.qacc.copy()

        ex = fs.solve(q, np.zeros(n), tau)             # gravity: -model.gravity (same as MJ)
        G = ex.G
        # same problem up to MuJoCo's regularizer: our QP with G + R reproduces MuJoCo
        mu_reg = fs.box_qp(G + np.diag(R), ex.qdd0, f)
        np.testing.assert_allclose(mu_reg, mu_mj, atol=1e-7 * f.max())
        np.testing.assert_allclose(ex.qdd0 + G @ mu_reg, qdd_mj, atol=1e-7)
        # exact solution vs MuJoCo within the regularization bound
        lam = np.linalg.eigvalsh(G)
        tol = lam[-1] / lam[0] * np.linalg.norm(R * mu_mj) + 1e-9
        assert np.linalg.norm(ex.qdd - qdd_mj) <= tol
        assert tol < 0.05 * max(1.0, np.linalg.norm(ex.qdd))
        # stick/slip agree wherever the exact margin exceeds the regularization effect
        dmu = np.linalg.norm(R * mu_mj) / lam[0]        # bound on |mu_exact - mu_mj|
        ambiguous = (ex.stick & (f - np.abs(ex.mu) <= 2 * dmu)) | (
            ~ex.stick & (np.abs(ex.qdd) <= 2 * tol))
        if ambiguous.any():
            continue
        compared += 1
        stick_mj = np.abs(mu_mj) < f * (1 - 1e-6)
        assert stick_mj.tolist() == ex.stick.tolist()
        seen['stick'] += int(ex.stick.sum())
        seen['slip'] += int((~ex.stick).sum())
    assert all(w.number == 0 for w in data.warning)      # no MuJoCo warning at all
    assert compared >= draws // 2
    assert seen['stick'] > 0 and seen['slip'] > 0
