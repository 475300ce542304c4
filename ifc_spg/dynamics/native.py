"""The compiled Popov-Vereshchagin kernel, or None where it was not built.

``ifc_spg.dynamics._native_dynamics`` is built from ``_native_dynamics.c`` at install time.

The numpy kernel (:class:`ifc_spg.dynamics.vereshchagin.NumpyKernel`) is the reference the
tests compare it with, and runs wherever the module is missing. ``IFC_SPG_NATIVE=0`` in the
environment selects the numpy code, as for the SPG tick's kernels (:mod:`ifc_spg.kernels`).
A solver picks its kernel when it is created.
"""

import os
from typing import Any

import numpy as np

__all__ = ['module', 'describe', 'NativeKernel']


def _load():
    if os.environ.get('IFC_SPG_NATIVE', '1').strip() == '0':
        return None
    try:
        import ifc_spg.dynamics._native_dynamics as _native_dynamics
    except ImportError:
        return None
    return _native_dynamics


module = _load()


def describe():
    """'native (C)' or 'numpy (...)': which kernel new solvers use by default, and why."""
    if module is not None:
        return 'native (C sweeps)'
    if os.environ.get('IFC_SPG_NATIVE', '1').strip() == '0':
        return 'numpy (IFC_SPG_NATIVE=0)'
    return 'numpy (ifc_spg.dynamics._native_dynamics was not built: reinstall with a C compiler)'


def _compiled():
    """The compiled module even under IFC_SPG_NATIVE=0 (tests compare both), or None."""
    try:
        import ifc_spg.dynamics._native_dynamics as _native_dynamics
    except ImportError:
        return None
    return _native_dynamics


_mod: Any = _compiled()  # the C extension (no stubs): its Kernel is the base class below

if _mod is not None:
    class NativeKernel(_mod.Kernel):
        """The compiled sweeps of one chain (workspace allocated once, here).

        Same methods and results as :class:`~ifc_spg.dynamics.vereshchagin.NumpyKernel`;
        ``solve`` and ``friction`` are the C methods, called directly.

        Args:
            chain: The :class:`~ifc_spg.dynamics.chain.Chain`.
            gravity0: Default base acceleration (6,) (−g).
            rank_tol: See :class:`~ifc_spg.dynamics.VereshchaginSolver`.
            damping: See :class:`~ifc_spg.dynamics.VereshchaginSolver`.
            result_type: The result class, built from the 11 fields in order.
            check: ``check(q, qd, tau, a0, fext, A, b)``, called on inputs the kernel
                rejects (wrong shape, not finite): it raises the error with its message.
        """

        def __new__(cls, chain, gravity0, rank_tol, damping, result_type, check):
            """The C kernel of ``chain``, its workspace allocated once."""
            return super().__new__(
                cls, n=chain.n, nq=chain.model.nq, revolute=chain.revolute.astype(float),
                axis=chain.axis, axis_skew=chain.axis_skew, axis_skew2=chain.axis_skew2,
                R_parent=chain.R_parent, p_parent=chain.p_parent, mass=chain.mass,
                com=chain.com, inertia_com=chain.inertia_com, armature=chain.armature,
                idx_q=chain.idx_q.astype(float), unbounded=chain.unbounded.astype(float),
                tip_placement=chain.tip_placement, gravity0=gravity0, rank_tol=rank_tol,
                damping=damping, result_type=result_type, check=check)

        def sensitivity(self, q, qd, tau, joints, a0, fext, A, b):
            """``(base, G, combine)``: see ``VereshchaginSolver.solve_with_sensitivity``.

            ``combine(mu)`` runs the sweeps again for τ + Σ μ_k e_joints[k] (q̈ is affine in
            τ, so this equals the column combination of the numpy kernel).
            """
            base, G = super().sensitivity(q, qd, tau, joints, a0, fext, A, b)
            G.setflags(write=False)
            joints = np.asarray(joints, dtype=int).reshape(-1)
            args = [None if x is None else np.array(x, dtype=float)
                    for x in (q, qd, a0, fext, A, b)]
            q, qd, a0, fext, A, b = args
            tau0 = base.tau_control - base.tau_constraint

            def combine(mu, gauss=False):
                t = tau0.copy()
                t[joints] += np.asarray(mu, dtype=float).reshape(joints.size)
                return self.solve(q, qd, t, a0, fext, A, b, gauss)

            return base, G, combine
else:  # not built: the name says so (VereshchaginSolver checks it)
    NativeKernel = None  # type: ignore[misc,assignment]
