"""Popov-Vereshchagin constrained hybrid dynamics of serial chains (docs/SPEC.md §9, [R Alg. 1]).

Given q, q̇, feed-forward torques τ, the base acceleration Ẍ_0, external wrenches on the
segments and m ≤ 6 acceleration constraints A_Nᵀ Ẍ_N = b_N on the last segment, the
solver returns the Gauss-principle motion

    q̈ = argmin ½ (q̈ − q̈_free)ᵀ M (q̈ − q̈_free)   s.t.   A_Nᵀ Ẍ_N(q̈) = b_N,

the constraint force magnitudes ν, the control torques and the segment accelerations,
in three O(n) sweeps (no n×n matrix is ever formed).

Implementation: the sweeps run in base ("ground") coordinates, Featherstone style. All
quantities that do not depend on the recursion (poses, joint motion subspaces S_i,
velocities as a cumulative sum, bias accelerations c_i, world inertias, bias forces) are
computed for all segments at once with numpy; only the articulated-inertia recursion
(inward) and the acceleration recursion (outward) loop over the joints, one small
rank-1 update per joint. The inward sweep carries several right-hand sides at once
(columns of torques), so the response of q̈ to unit joint torques, ∂q̈/∂τ, comes out of
the same pass (used by the static-friction extension).

Two kernels run these sweeps, chosen once per solver (``kernel=``): :class:`NumpyKernel`
here, the reference, and the same steps in C (``_native_dynamics.c``, wrapped by
:class:`ifc_spg.dynamics.native.NativeKernel`), ~40x faster: one workspace per chain, no
allocation per call but the result's arrays. The C kernel is the default where it was
built; ``IFC_SPG_NATIVE=0`` selects numpy. Both give the same results to round-off
(test/test_dynamics_native.py). ``ifc-spg dynamics bench`` times both next to KDL.

Conventions:
    * Spatial vectors are [linear; angular]; wrenches [force; moment].
    * The constrained acceleration Ẍ_N is the *spatial* acceleration of the tip frame
      (KDL's convention, pinocchio ``getFrameAcceleration(..., LOCAL_WORLD_ALIGNED)``):
      the derivative of the tip's body twist, rotated into base axes, referenced at the
      tip frame origin. Its linear part is the classical acceleration p̈ minus ω × v
      (classical = spatial + [ω × v; 0]). To constrain the classical acceleration, move
      ω × v to b_N.
    * A_N (6×m) holds unit constraint *wrenches* on the last segment, base axes, reference
      point at the tip frame origin. ν has the sign of KDL and report Alg. 1 line 25:
      the wrench the constraint exerts on the last segment is **−A_N ν** (A_N ν is the
      wrench the segment exerts on the constraint), so τ_control = τ − J_Nᵀ A_N ν.
    * Base acceleration Ẍ_0 = [linear; angular] spatial acceleration of the base, base
      axes, at the base origin. Gravity enters as Ẍ_0 = −g (default: −model.gravity).
    * External wrenches act *on* segment i, base axes, reference point at the origin of
      joint frame i (pinocchio LOCAL_WORLD_ALIGNED at the joint).
    * Segment accelerations are returned in the same convention as Ẍ_N, per joint frame.
      Like KDL, all segment accelerations (and hence Ẍ_N in the constraint) include Ẍ_0:
      with gravity as Ẍ_0 = −g a segment at rest has Ẍ = [0, 0, +9.81, 0, 0, 0]. To
      constrain the acceleration relative to the base, use b_N = A_Nᵀ(a_rel + Ẍ_0 moved
      to the tip origin).
    * Reference for tests: the constrained Gauss problem built from pinocchio's M, the
      LOCAL_WORLD_ALIGNED frame Jacobian J and drift J̇q̇ = getFrameAcceleration(...,
      LOCAL_WORLD_ALIGNED) at q̈ = 0 (plus Ẍ_0 moved to the tip) gives the same q̈.
"""

from collections.abc import Callable
from dataclasses import dataclass
import functools
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike

from ifc_spg.dynamics import native
from ifc_spg.dynamics.box_qp import box_qp
from ifc_spg.dynamics.chain import chain_from_model
from ifc_spg.errors import ParameterError, SolverError, did_you_mean

__all__ = ['KERNELS', 'NumpyKernel', 'VereshchaginResult', 'VereshchaginSolver',
           'check_inputs', 'default_kernel']


@dataclass(frozen=True)
class VereshchaginResult:
    """Output of :meth:`VereshchaginSolver.solve`.

    Attributes:
        qdd: Joint accelerations q̈ in [rad/s^2] or [m/s^2], shape (n,).
        nu: Constraint force magnitudes ν, shape (m,); the constraint exerts −A_N ν on the
            last segment (KDL sign).
        tau_control: Control torques τ − J_Nᵀ A_N ν in [Nm] / [N], shape (n,): applied
            as joint torques without the constraint (e.g. to ABA) they produce ``qdd``.
        tau_constraint: The constraint part −J_Nᵀ A_N ν, shape (n,).
        segment_accelerations: Spatial accelerations of the joint frames, base axes,
            [linear; angular], shape (n, 6) (includes the base acceleration, i.e. −g).
        tip_acceleration: Spatial acceleration Ẍ_N of the tip frame, shape (6,).
        constraint_residual: A_Nᵀ Ẍ_N − b_N, shape (m,) (≈ 0 unless ``singular``).
        singular: True when the constraint coupling matrix 𝓛 is rank-deficient
            (singular configuration or more constraints than DoF); ν is then the damped
            least-squares solution and the constraints hold only as far as possible.
        rank: Numerical rank of 𝓛.
        coupling: The constraint coupling matrix 𝓛_0, shape (m, m) (negative semidefinite).
        gauss: Acceleration energy Z(q̈) in [Nm/s^2] (report eq. 4.1 with the torques that
            were applied), or NaN unless requested with ``gauss=True``.
    """

    qdd: np.ndarray
    nu: np.ndarray
    tau_control: np.ndarray
    tau_constraint: np.ndarray
    segment_accelerations: np.ndarray
    tip_acceleration: np.ndarray
    constraint_residual: np.ndarray
    singular: bool
    rank: int
    coupling: np.ndarray
    gauss: float


_outer = np.multiply.outer


def _skew_map(dim):
    """Constant E with (x @ E).reshape(-1, dim, dim) = the cross-product matrix of x."""
    if dim == 3:
        E = np.zeros((3, 3, 3))
        for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
            E[i, k, j] = 1.0       # [x]_kj = x_i for (k, j) = (2, 1) ...
            E[i, j, k] = -1.0
        return E.reshape(3, 9)
    # motion cross product crm(v) = [[w^, vl^], [0, w^]] for v = [vl; w]
    S3 = _skew_map(3).reshape(3, 3, 3)
    E = np.zeros((6, 6, 6))
    E[3:, :3, :3] = S3
    E[3:, 3:, 3:] = S3
    E[:3, :3, 3:] = S3
    return E.reshape(6, 36)


_SKEW3 = _skew_map(3)
_CRM = _skew_map(6)


def check_inputs(chain, gravity0, q, qd, tau, a0, fext, A, b):
    """Validate and convert the inputs of a solve (the boundary: messages name the fix).

    Args:
        chain: The :class:`~ifc_spg.dynamics.chain.Chain`.
        gravity0: Base acceleration used when ``a0`` is None, shape (6,).
        q: Configuration, as :meth:`VereshchaginSolver.solve`.
        qd: Joint velocities.
        tau: Feed-forward joint torques, or None (zero).
        a0: ``base_acceleration``, or None (``gravity0``).
        fext: ``external_wrenches``, or None.
        A: ``A_N``, or None (no constraint).
        b: ``b_N``, or None (zero).

    Returns:
        ``(th, qd, tau, a0, fext, A, b)`` as float arrays: joint angles (n,), qd (n,),
        tau (n,), a0 (6,), fext (n, 6) or None, A (6, m), b (m,).

    Raises:
        ParameterError: An input has the wrong shape or is not finite.
        ModelError: ``q`` does not have pinocchio's nq entries.
    """
    n = chain.n
    th = chain.joint_angles(q)
    qd = np.asarray(qd, dtype=float)
    if qd.shape != (n,):
        raise ParameterError(f'qd must have shape ({n},), got {qd.shape}')
    if tau is None:
        tau = np.zeros(n)
    else:
        tau = np.asarray(tau, dtype=float)
        if tau.shape != (n,):
            raise ParameterError(f'tau must have shape ({n},), got {tau.shape}')
    a0 = gravity0 if a0 is None else _base_acceleration(a0)
    if fext is not None:
        fext = np.asarray(fext, dtype=float)
        if fext.shape != (n, 6):
            raise ParameterError(f'external_wrenches must have shape ({n}, 6) (one '
                                 f'[force; moment] per segment), got {fext.shape}')
    A, b = _constraint(A, b)
    for name, x in (('q', th), ('qd', qd), ('tau', tau), ('base_acceleration', a0),
                    ('A_N', A), ('b_N', b)):
        if not np.isfinite(x).all():
            raise ParameterError(f'{name} must be finite, got {np.asarray(x).tolist()}')
    if fext is not None and not np.isfinite(fext).all():
        raise ParameterError('external_wrenches must be finite')
    return th, qd, tau, a0, fext, A, b


def _base_acceleration(a0):
    """``base_acceleration`` as a float array (6,) (ParameterError for another shape)."""
    a0 = np.asarray(a0, dtype=float)
    if a0.shape != (6,):
        raise ParameterError(f'base_acceleration must have shape (6,) [linear; '
                             f'angular], got {a0.shape}; gravity enters as -g, e.g. '
                             '[0, 0, 9.81, 0, 0, 0]')
    return a0


def _constraint(A, b):
    """``(A_N (6, m), b_N (m,))`` as float arrays; none given: m = 0 (ParameterError)."""
    if A is None:
        if b is not None and np.size(b):
            raise ParameterError('b_N given without A_N')
        return np.zeros((6, 0)), np.zeros(0)
    A = np.asarray(A, dtype=float)
    if A.ndim == 1:
        A = A[:, None]
    if A.ndim != 2 or A.shape[0] != 6 or A.shape[1] > 6:
        raise ParameterError(f'A_N must have shape (6, m) with m <= 6 (one unit '
                             f'constraint wrench per column), got {A.shape}')
    b = np.zeros(A.shape[1]) if b is None else np.asarray(b, dtype=float).reshape(-1)
    if b.shape != (A.shape[1],):
        raise ParameterError(f'b_N must have shape ({A.shape[1]},) to match the '
                             f'{A.shape[1]} columns of A_N, got {b.shape}')
    return A, b


class DynamicsKernel(Protocol):
    """What a solver needs of its kernel: :class:`NumpyKernel` or ``native.NativeKernel``.

    The inputs are those of :func:`check_inputs` (array-likes, None where optional).
    """

    def solve(self, q: ArrayLike, qd: ArrayLike, tau: ArrayLike | None, a0: ArrayLike | None,
              fext: ArrayLike | None, A: ArrayLike | None, b: ArrayLike | None,
              gauss: bool) -> 'VereshchaginResult':
        """One solve (:meth:`VereshchaginSolver.solve`)."""
        ...

    def sensitivity(self, q: ArrayLike, qd: ArrayLike, tau: ArrayLike | None, joints: ArrayLike,
                    a0: ArrayLike | None, fext: ArrayLike | None, A: ArrayLike | None,
                    b: ArrayLike | None) -> tuple['VereshchaginResult', np.ndarray,
                                                  Callable[..., 'VereshchaginResult']]:
        """``(base, G, combine)`` (:meth:`VereshchaginSolver.solve_with_sensitivity`)."""
        ...

    def friction(self, q: ArrayLike, qd: ArrayLike, tau: ArrayLike | None, a0: ArrayLike | None,
                 fext: ArrayLike | None, A: ArrayLike | None, b: ArrayLike | None,
                 breakaway: np.ndarray, eps: float) -> tuple['VereshchaginResult', np.ndarray,
                                                             np.ndarray, np.ndarray, np.ndarray,
                                                             np.ndarray, bool]:
        """The exact static-friction solve (:meth:`NumpyKernel.friction`)."""
        ...


class NumpyKernel:
    """The sweeps in numpy: the reference of the compiled kernel and its fallback.

    One per solver (:class:`VereshchaginSolver` picks it with ``kernel='numpy'``); same
    methods and results as :class:`ifc_spg.dynamics.native.NativeKernel`.

    Args:
        chain: The :class:`~ifc_spg.dynamics.chain.Chain`.
        gravity0: Default base acceleration (6,) (−g).
        rank_tol: See :class:`VereshchaginSolver`.
        damping: See :class:`VereshchaginSolver`.
    """

    def __init__(self, chain, gravity0, rank_tol, damping):
        self.chain = c = chain
        self.n = n = chain.n
        self.rank_tol = rank_tol
        self.damping = damping
        self._gravity0 = gravity0
        self._revf = c.revolute.astype(float)
        self._prisf = 1.0 - self._revf
        self._rev3 = c.revolute[:, None]
        self._H = np.zeros((n, 4, 4))
        self._H[:, 3, 3] = 1.0
        self._T = np.zeros((n, 4, 4))
        self._eye3 = np.eye(3)
        self._mI = c.mass[:, None, None] * np.eye(3)

    def solve(self, q, qd, tau, a0, fext, A, b, gauss):
        """:meth:`VereshchaginSolver.solve` with positional arguments."""
        th, qd, tau, a0, fext, A, b = check_inputs(self.chain, self._gravity0, q, qd, tau, a0,
                                                   fext, A, b)
        out = self._sweeps(th, qd, tau[:, None], a0, fext, A, b)
        return self._result(out, np.ones(1), tau, A, b, gauss)

    def sensitivity(self, q, qd, tau, joints, a0, fext, A, b):
        """``(base, G, combine)`` of :meth:`VereshchaginSolver.solve_with_sensitivity`."""
        th, qd, tau, a0, fext, A, b = check_inputs(self.chain, self._gravity0, q, qd, tau, a0,
                                                   fext, A, b)
        joints = np.asarray(joints, dtype=int).reshape(-1)
        k = joints.size
        T = np.zeros((self.n, 1 + k))
        T[:, 0] = tau
        T[joints, 1 + np.arange(k)] = 1.0
        out = self._sweeps(th, qd, T, a0, fext, A, b)
        G = out['qdd'][:, 1:].copy()
        G.setflags(write=False)

        def combine(mu, gauss=False):
            mu = np.asarray(mu, dtype=float).reshape(k)
            t = tau.copy()
            t[joints] += mu
            return self._result(out, np.concatenate(([1.0], mu)), t, A, b, gauss)

        return self._result(out, np.concatenate(([1.0], np.zeros(k))), tau, A, b, False), G, \
            combine

    def friction(self, q, qd, tau, a0, fext, A, b, breakaway, eps):
        """The exact static-friction solve (one pass, one box QP), see static_friction.py.

        Returns:
            ``(result, mu, stationary, stick, qdd0, G, ok)``: the result at μ* (with the
            acceleration energy), μ* (n,), the joints at rest (|qd_j| ≤ eps, f_j > 0), the
            ones that stick, q̈(0), G (k, k) symmetrized, and whether the box QP's answer
            passed its KKT check.
        """
        qd_ok = check_inputs(self.chain, self._gravity0, q, qd, tau, a0, fext, A, b)[1]
        joints = np.flatnonzero((np.abs(qd_ok) <= eps) & (breakaway > 0))
        base, Gfull, combine = self.sensitivity(q, qd, tau, joints, a0, fext, A, b)
        G = Gfull[joints]
        G = 0.5 * (G + G.T)
        f = breakaway[joints]
        mu_s, ok = box_qp(G, base.qdd[joints], f)
        res = combine(mu_s, gauss=True)
        n = self.n
        mu = np.zeros(n)
        mu[joints] = mu_s
        stationary = np.zeros(n, dtype=bool)
        stationary[joints] = True
        stick = np.zeros(n, dtype=bool)
        # strictly inside the box <=> zero acceleration (KKT); tolerance relative to f
        stick[joints] = np.abs(mu_s) < f * (1.0 - 1e-7)
        return res, mu, stationary, stick, base.qdd, G, ok

    # -- the three sweeps ------------------------------------------------------------------
    def _sweeps(self, th, qd, T, a0, fext, A, b):
        """Run the sweeps for the torque columns T (n, r); column 0 carries the bias terms."""
        Tw, S, cb, Iw, pb = self._outward_bias(th, qd, fext)
        p = Tw[:, :3, 3]
        ptip = (Tw[self.n - 1] @ self.chain.tip_placement)[:3, 3]
        Aw = np.empty((6, A.shape[1]))               # A_N moved to the base origin
        Aw[:3] = A[:3]
        Aw[3:] = A[3:] + (ptip @ _SKEW3).reshape(3, 3) @ A[:3]
        xs, Ds, Es, E0 = self._inward(S, cb, Iw, pb, T, Aw)
        nu, L, rank, singular, K, Uv = self._balance(xs, Ds, Es, E0, cb, a0, b, T.shape[1])
        qdd, acc = self._outward_accelerations(S, cb, a0, K, Uv)
        return {'qdd': qdd, 'acc': acc, 'nu': nu, 'L': L, 'rank': rank, 'singular': singular,
                'S': S, 'p': p, 'ptip': ptip, 'Aw': Aw, 'Iw': Iw, 'pb': pb}

    def _poses(self, th):
        """Outward sweep 1a: the joint frames' poses in base coordinates, (n, 4, 4).

        Writes the workspace arrays of this kernel (the result is one of them).
        """
        c = self.chain
        s = np.sin(th) * self._revf
        cm = (1.0 - np.cos(th)) * self._revf
        Rj = self._eye3 + s[:, None, None] * c.axis_skew + cm[:, None, None] * c.axis_skew2
        H = self._H
        np.matmul(c.R_parent, Rj, out=H[:, :3, :3])
        H[:, :3, 3] = c.p_parent + np.einsum('nij,nj->ni', c.R_parent,
                                             c.axis * (th * self._prisf)[:, None])
        Tw = self._T
        Tw[0] = H[0]
        for i in range(1, self.n):                  # pose composition (the only loop here)
            np.matmul(Tw[i - 1], H[i], out=Tw[i])
        return Tw

    def _inertias(self, R, p):
        """Outward sweep 1c: the spatial inertias in base coordinates (at the base origin)."""
        c = self.chain
        n = self.n
        cw = p + np.einsum('nij,nj->ni', R, c.com)
        Icw = R @ c.inertia_com @ R.transpose(0, 2, 1)
        C = (cw @ _SKEW3).reshape(n, 3, 3)
        mC = c.mass[:, None, None] * C
        Iw = np.empty((n, 6, 6))
        Iw[:, :3, :3] = self._mI
        Iw[:, :3, 3:] = -mC
        Iw[:, 3:, :3] = mC
        Iw[:, 3:, 3:] = Icw - mC @ C
        return Iw

    def _outward_bias(self, th, qd, fext):
        """Outward sweep 1: poses, motion subspaces, bias accelerations and forces.

        Returns:
            ``(Tw, S, cb, Iw, pb)``: poses (n, 4, 4), motion subspaces S_i (n, 6), bias
            accelerations c_i (n, 6), spatial inertias (n, 6, 6) and bias forces (n, 6),
            all in base coordinates.
        """
        n = self.n
        Tw = self._poses(th)
        R = Tw[:, :3, :3]
        p = Tw[:, :3, 3]
        z = np.einsum('nij,nj->ni', R, self.chain.axis)  # joint axes in base axes
        S = np.empty((n, 6))                         # motion subspaces, base coordinates
        pz = ((p @ _SKEW3).reshape(n, 3, 3) @ z[:, :, None])[:, :, 0]  # p x z
        S[:, :3] = np.where(self._rev3, pz, z)
        S[:, 3:] = z * self._revf[:, None]
        Sq = S * qd[:, None]
        V = np.cumsum(Sq, axis=0)                    # segment velocities
        crm = (V @ _CRM).reshape(n, 6, 6)           # v x (motion cross product)
        Iw = self._inertias(R, p)
        h = (Iw @ V[:, :, None])
        cb = (crm @ Sq[:, :, None])[:, :, 0]         # c_i = v_i x S_i qd_i
        pb = -(crm.transpose(0, 2, 1) @ h)[:, :, 0]  # v_i x* I_i v_i  (x* = -crm^T)
        if fext is not None:
            pb[:, :3] -= fext[:, :3]
            pb[:, 3:] -= fext[:, 3:] + (
                (p @ _SKEW3).reshape(n, 3, 3) @ fext[:, :3, None])[:, :, 0]
        return Tw, S, cb, Iw, pb

    def _inward(self, S, cb, Iw, pb, T, Aw):
        """Inward sweep: articulated inertias, bias forces, constraint propagation.

        Mx = [I^A | p^A (r columns) | E (m columns)] of the current articulated body; one
        rank-1 update per joint projects all of them (report Alg. 1, lines 13-21).

        Returns:
            ``(xs, Ds, Es, E0)``: per joint [U_i | S^T p^A - tau | S^T E_i] (n, k), D_i
            (n,), E_{i-1} = P_i E_i (n, 6, m), and E_0 (6, m) at the base.
        """
        n = self.n
        r = T.shape[1]
        m = Aw.shape[1]
        k = 6 + r + m
        Aug = np.zeros((n, 6, k))                    # rigid-body terms added per segment
        Aug[:, :, :6] = Iw
        Aug[:, :, 6] = pb
        Taug = np.zeros((n, k))
        Taug[:, 6:6 + r] = T
        Mx = np.zeros((6, k))
        Mx[:, 6 + r:] = Aw
        xs = np.empty((n, k))                        # [U_i | S^T p^A - tau | S^T E_i]
        Ds = np.empty(n)
        Es = np.empty((n, 6, m))                     # E_{i-1} = P_i E_i
        d = self.chain.armature
        for i in range(n - 1, -1, -1):
            Mx += Aug[i]
            Si = S[i]
            x = Si @ Mx
            D = d[i] + x[:6] @ Si
            x -= Taug[i]
            Mx -= _outer(x[:6] / D, x)
            Mx[:, 6] += Mx[:, :6] @ cb[i]            # + I^a c_i
            xs[i] = x
            Ds[i] = D
            Es[i] = Mx[:, 6 + r:]
        return xs, Ds, Es, Mx[:, 6 + r:]

    def _balance(self, xs, Ds, Es, E0, cb, a0, b, r):
        """Balance of acceleration energy at the base: nu = L0^-1 (b - E0^T a0 - U0).

        Returns:
            ``(nu, L, rank, singular, K, Uv)``: constraint magnitudes (m, r), the coupling
            matrix L0 (m, m), its numerical rank, whether it is rank-deficient, and the
            terms of the outward sweep (n, r) and (n, 6).
        """
        m = E0.shape[1]
        Uv = xs[:, :6] / Ds[:, None]
        u = -xs[:, 6:6 + r]
        if not m:
            return np.zeros((0, r)), np.zeros((0, 0)), 0, False, u / Ds[:, None], Uv
        sE = xs[:, 6 + r:]
        sED = sE / Ds[:, None]
        L = -(sED.T @ sE)
        U0 = sED.T @ u
        U0[:, 0] += np.einsum('nkm,nk->m', Es, cb)
        rhs = -U0
        rhs[:, 0] += b - E0.T @ a0
        lam, vec = np.linalg.eigh(-L)                # -L is symmetric positive semidefinite
        lmax = max(lam[-1], 0.0)
        tol = self.rank_tol * lmax
        rank = int(np.count_nonzero(lam > tol)) if lmax > 0 else 0
        singular = rank < m
        if singular:
            delta2 = (self.damping * lmax) ** 2 if lmax > 0 else 1e-300
            inv = lam / (lam * lam + delta2)
        else:
            inv = 1.0 / lam
        nu = -(vec * inv) @ (vec.T @ rhs)            # L^-1 = -V diag(1/lam) V^T
        K = (u - sE @ nu) / Ds[:, None]
        return nu, L, rank, singular, K, Uv

    def _outward_accelerations(self, S, cb, a0, K, Uv):
        """Outward sweep 2: joint accelerations (n, r) and segment accelerations (n, 6, r).

        a_i = a0 + C_i + sum_{k<=i} S_k qdd_k with C_i = sum_{k<=i} c_k (cumulative sum).
        Subtracts the bias of column 0 from ``K`` in place.
        """
        n = self.n
        r = K.shape[1]
        Cb = np.cumsum(cb, axis=0) + a0
        K[:, 0] -= np.einsum('ni,ni->n', Uv, Cb)
        qdd = np.empty((n, r))
        a = np.zeros((6, r))
        for i in range(n):
            qi = K[i] - Uv[i] @ a
            a += _outer(S[i], qi)
            qdd[i] = qi
        acc = np.cumsum(S[:, :, None] * qdd[:, None, :], axis=0)
        acc[:, :, 0] += Cb
        return qdd, acc

    def _result(self, out, wts, tau, A, b, gauss):
        """Combine the columns of a sweep with weights ``wts`` into a result."""
        qdd = out['qdd'] @ wts
        nu = out['nu'] @ wts
        acc = out['acc'] @ wts                       # (n, 6), base coordinates
        S, p = out['S'], out['p']
        tau_c = -(S @ (out['Aw'] @ nu))
        seg = acc.copy()                             # shift to the joint-frame origins
        seg[:, :3] -= ((p @ _SKEW3).reshape(-1, 3, 3) @ acc[:, 3:, None])[:, :, 0]
        a_n = acc[-1]
        tip = a_n.copy()
        tip[:3] -= (out['ptip'] @ _SKEW3).reshape(3, 3) @ a_n[3:]
        zval = np.nan
        if gauss:
            Iw, pb = out['Iw'], out['pb']
            zval = float(0.5 * np.einsum('ni,nij,nj->', acc, Iw, acc) + np.sum(pb * acc)
                         + 0.5 * np.sum(self.chain.armature * qdd * qdd) - tau @ qdd)
        return VereshchaginResult(
            qdd=qdd, nu=nu, tau_control=tau + tau_c, tau_constraint=tau_c,
            segment_accelerations=seg, tip_acceleration=tip,
            constraint_residual=A.T @ tip - b, singular=out['singular'], rank=out['rank'],
            coupling=out['L'], gauss=zval)


KERNELS = ('native', 'numpy')


def default_kernel():
    """The kernel new solvers use: 'native' or 'numpy'.

    'native' where the C module was built (and ``IFC_SPG_NATIVE`` is not 0), else 'numpy'
    (see :func:`ifc_spg.dynamics.native.describe`).
    """
    return 'native' if native.module is not None else 'numpy'


class VereshchaginSolver:
    """Popov-Vereshchagin hybrid dynamics solver for a serial chain.

    Args:
        model: pinocchio ``Model`` (or :class:`ifc_spg.RobotModel`) of a fixed-base
            serial chain of revolute / continuous / prismatic joints. Rotor inertias are
            taken from ``model.armature``. The model is not modified.
        tip_frame: Frame on the last segment where A_N acts (default: last joint frame).
        rank_tol: 𝓛 counts as rank-deficient when its smallest eigenvalue magnitude is
            below ``rank_tol`` times the largest.
        damping: Relative damping δ of the damped least-squares inverse used when 𝓛 is
            rank-deficient: ν = argmin ‖𝓛ν − r‖² + (δ λ_max)² ‖ν‖².
        kernel: ``'native'`` (the sweeps in C, ``_native_dynamics.c``) or ``'numpy'``
            (the reference); default :func:`default_kernel`. Both give the same results
            (to round-off); the choice is made here, once.

    Raises:
        SolverError: Unknown ``kernel``, or ``'native'`` where it was not built.
    """

    def __init__(self, model, *, tip_frame=None, rank_tol=1e-9, damping=1e-6, kernel=None):
        self.chain = chain_from_model(model, tip_frame)
        self.model = self.chain.model
        self.n = self.chain.n
        if not rank_tol > 0 or not damping > 0:
            raise ParameterError(f'rank_tol and damping must be > 0, got rank_tol={rank_tol}, '
                                 f'damping={damping}')
        self.rank_tol = float(rank_tol)
        self.damping = float(damping)
        gravity0 = -np.asarray(self.model.gravity.vector, dtype=float)
        gravity0.setflags(write=False)
        name = default_kernel() if kernel is None else kernel
        if name not in KERNELS:
            raise SolverError(f"unknown dynamics kernel '{name}'{did_you_mean(name, KERNELS)}"
                              f"; available: {', '.join(KERNELS)}")
        if name == 'native':
            if native.NativeKernel is None:
                raise SolverError("kernel='native' needs ifc_spg.dynamics._native_dynamics, "
                                  "which was not built; reinstall with a C compiler "
                                  "(./run setup) or use kernel='numpy'")
            check = functools.partial(check_inputs, self.chain, gravity0)
            self.kernel: DynamicsKernel = native.NativeKernel(self.chain, gravity0, self.rank_tol,
                                              self.damping, VereshchaginResult, check)
        else:
            self.kernel = NumpyKernel(self.chain, gravity0, self.rank_tol, self.damping)
        self.kernel_name = name

    # -- public API ------------------------------------------------------------------------
    def solve(self, q, qd, tau=None, *, base_acceleration=None, external_wrenches=None,
              A_N=None, b_N=None, gauss=False):
        """Solve the constrained hybrid dynamics problem once.

        Args:
            q: Configuration, pinocchio convention, shape (nq,) [rad] / [m].
            qd: Joint velocities, shape (n,) [rad/s] / [m/s].
            tau: Feed-forward joint torques, shape (n,) [Nm] / [N] (default 0).
            base_acceleration: Ẍ_0, shape (6,) [m/s^2, rad/s^2]; default −model.gravity.
            external_wrenches: Wrenches on the segments, shape (n, 6) [N, Nm] (see module
                docstring for frames), or None.
            A_N: Unit constraint wrenches on the last segment, shape (6, m), m ≤ 6.
            b_N: Desired constraint accelerations ("acceleration energy"), shape (m,).
            gauss: Also evaluate the acceleration energy Z(q̈).

        Returns:
            VereshchaginResult.

        Raises:
            ParameterError: An input has the wrong shape or is not finite.
            ModelError: ``q`` does not have pinocchio's nq entries.
        """
        return self.kernel.solve(q, qd, tau, base_acceleration, external_wrenches, A_N, b_N,
                                 gauss)

    def solve_with_sensitivity(self, q, qd, tau=None, *, joints=(), base_acceleration=None,
                               external_wrenches=None, A_N=None, b_N=None):
        """One pass giving q̈(τ) and the response of q̈ to unit torques at ``joints``.

        q̈ is affine in the joint torques, q̈(τ + Σ_j μ_j e_j) = q̈(τ) + G μ (report eq.
        5.10, the characteristic equation); the sweeps carry the unit-torque columns along
        with the actual right-hand side, so G costs no extra pass.

        Returns:
            ``(base, G, combine)`` where ``base`` is the :class:`VereshchaginResult` for
            ``tau``, ``G`` has shape (n, len(joints)) with G[:, k] = ∂q̈/∂τ_joints[k], and
            ``combine(mu, gauss=False)`` returns the full result for τ + Σ μ_k e_{joints[k]}
            without another pass.
        """
        return self.kernel.sensitivity(q, qd, tau, joints, base_acceleration,
                                       external_wrenches, A_N, b_N)
