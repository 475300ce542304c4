"""Static friction in the Popov-Vereshchagin solver (docs/SPEC.md §10, report Ch. 5).

Joints at rest (|q̇_j| ≤ ε, the set Θ₀) with breakaway torque f_j > 0 take a friction
torque μ_j ∈ [−f_j, f_j]. The true motion is the saddle point (report eq. 5.2/5.5)

    q̈* = argmin_q̈ max_{|μ_j| ≤ f_j} Z₀(q̈) − Σ_{j∈Θ₀} μ_j q̈_j.

Sign of μ: here μ_j is the friction torque *acting on* joint j (it is added to the
feed-forward torque, τ + μ). The report's eq. 5.7 writes τ − Wμ, which describes the
same set of motions with μ mirrored; its Ch. 6 numbers (μ* = +5 Nm against a −5 Nm
load) use the acting-torque sign that we use.

Exact method: q̈ is affine in μ, q̈(μ) = q̈(0) + G μ with G = ∂q̈/∂τ restricted to Θ₀
(report eq. 5.10; one solver pass gives both, see
:meth:`VereshchaginSolver.solve_with_sensitivity`). By the envelope theorem the dual
function g(μ) = min_q̈ Z is then the concave quadratic

    g(μ) = g(0) − q̈_Θ(0)ᵀ μ − ½ μᵀ G_ΘΘ μ,     G_ΘΘ = G_ΘΘᵀ ⪰ 0,

so μ* solves the box-constrained QP min ½ μᵀ G_ΘΘ μ + q̈_Θ(0)ᵀ μ, −f ≤ μ ≤ f, solved
exactly by the solver's kernel (``qp_solver='box'``, the default: the sweeps and an
active-set box QP in one compiled call, :mod:`ifc_spg.dynamics.box_qp`), or by proxsuite
or daqp. A joint sticks when |μ*_j| < f_j (then q̈_j = 0); at the bound it slips, with
q̈_j of the sign opposite to μ*_j.

Reference method (the report's): sample μ on a grid over the box, run the full solver
for each sample, keep the sample with the largest acceleration energy.
"""

from dataclasses import dataclass
import itertools

import numpy as np

from ifc_spg.dynamics.vereshchagin import VereshchaginSolver
from ifc_spg.errors import ParameterError, SolverError, did_you_mean

__all__ = ['FrictionResult', 'SamplingResult', 'StaticFrictionSolver', 'QP_SOLVERS']

QP_SOLVERS = ('box', 'proxsuite', 'daqp')


@dataclass(frozen=True)
class FrictionResult:
    """Output of :meth:`StaticFrictionSolver.solve`.

    Attributes:
        mu: Friction torques acting on the joints in [Nm] / [N], shape (n,) (0 for moving
            joints and joints without friction).
        stationary: Joints in Θ₀ (at rest with f_j > 0), shape (n,) bool.
        stick: Joints that stay at rest (stationary and |μ_j| < f_j), shape (n,) bool.
        qdd: True joint accelerations q̈(μ*), shape (n,).
        result: The full :class:`VereshchaginResult` at μ* (ν, τ_control, ...).
        qdd0: q̈(0), the motion without friction, shape (n,).
        G: ∂q̈_Θ/∂μ_Θ, shape (k, k) for the k stationary joints (symmetric PSD).
        gauss: Acceleration energy at the optimum, g(μ*) [Nm/s^2].
    """

    mu: np.ndarray
    stationary: np.ndarray
    stick: np.ndarray
    qdd: np.ndarray
    result: object
    qdd0: np.ndarray
    G: np.ndarray
    gauss: float


@dataclass(frozen=True)
class SamplingResult:
    """Output of :meth:`StaticFrictionSolver.solve_sampling` (report's reference method).

    Attributes:
        mu: Best sample μ (acting friction torques), shape (n,).
        qdd: q̈ at the best sample, shape (n,).
        gauss: Acceleration energy at the best sample.
        samples: All sampled μ_Θ, shape (s, k).
        gauss_samples: Z at each sample, shape (s,).
        qdd_samples: q̈ at each sample, shape (s, n).
        joints: Indices of the stationary joints (columns of ``samples``).
    """

    mu: np.ndarray
    qdd: np.ndarray
    gauss: float
    samples: np.ndarray
    gauss_samples: np.ndarray
    qdd_samples: np.ndarray
    joints: np.ndarray


def _polish(G, g, f, mu):
    """Make a QP solver's μ exact: fix the active bounds, solve the free part, verify KKT.

    Interior-point / ALM solvers (proxsuite) stop a little inside active bounds; with the
    active set guessed from their answer the problem is a small linear solve. The polished
    point is kept only if it satisfies the KKT conditions, else ``mu`` is returned.
    """
    tol = 1e-6 * f
    upper = mu >= f - tol
    lower = mu <= -f + tol
    free = ~(upper | lower)
    x = np.where(upper, f, np.where(lower, -f, 0.0))
    if free.any():
        rhs = -(g[free] + G[np.ix_(free, ~free)] @ x[~free])
        x[free] = np.linalg.lstsq(G[np.ix_(free, free)], rhs, rcond=1e-12)[0]
    grad = G @ x + g
    scale = 1e-9 * max(1.0, float(np.max(np.abs(g))), float(np.max(np.abs(G)) * np.max(f)))
    ok = (np.all(np.abs(x[free]) <= f[free]) and np.all(grad[upper] <= scale)
          and np.all(grad[lower] >= -scale) and np.all(np.abs(grad[free]) <= scale))
    return x if ok else mu


class StaticFrictionSolver:
    """Popov-Vereshchagin solver with static (breakaway) joint friction.

    Args:
        solver: A :class:`VereshchaginSolver`, or a pinocchio model to build one from.
        breakaway: Breakaway torques f_j ≥ 0 in [Nm] / [N], scalar or shape (n,).
        eps: Velocity threshold ε for "at rest" in [rad/s] / [m/s].
        qp_solver: ``'box'`` (the kernel's exact active-set box QP, in the same call as the
            sweeps; proxsuite takes over if its answer fails the KKT check), ``'proxsuite'``
            or ``'daqp'``.
    """

    def __init__(self, solver, breakaway, *, eps=1e-6, qp_solver='box'):
        if not isinstance(solver, VereshchaginSolver):
            solver = VereshchaginSolver(solver)
        self.solver = solver
        n = solver.n
        f = np.array(np.broadcast_to(np.asarray(breakaway, dtype=float), (n,)))
        if not np.isfinite(f).all() or (f < 0).any():
            raise ParameterError(f'breakaway torques must be finite and >= 0, got {f.tolist()}')
        f.setflags(write=False)
        self.breakaway = f
        if not eps >= 0:
            raise ParameterError(f'eps must be >= 0 [rad/s], got {eps}')
        self.eps = float(eps)
        if qp_solver not in QP_SOLVERS:
            raise SolverError(f"unknown QP solver '{qp_solver}'"
                              f'{did_you_mean(qp_solver, QP_SOLVERS)}; available: '
                              f"{', '.join(QP_SOLVERS)}")
        self.qp_solver = qp_solver
        self._qp_cache = {}
        self._solve = self._solve_box if qp_solver == 'box' else self._solve_qp

    def stationary(self, qd):
        """Return the mask of joints in Θ₀: |q̇_j| ≤ ε and f_j > 0."""
        return (np.abs(np.asarray(qd, dtype=float)) <= self.eps) & (self.breakaway > 0)

    # -- exact method ----------------------------------------------------------------------
    def solve(self, q, qd, tau=None, *, base_acceleration=None, external_wrenches=None,
              A_N=None, b_N=None):
        """Exact static-friction solve: one solver pass plus one small box QP.

        Args:
            q: Configuration (pinocchio nq).
            qd: Joint velocities; joints with |qd_j| <= eps and f_j > 0 are at rest.
            tau: Feed-forward torques (friction is added to them).
            base_acceleration: As :meth:`VereshchaginSolver.solve`.
            external_wrenches: As :meth:`VereshchaginSolver.solve`.
            A_N: As :meth:`VereshchaginSolver.solve`.
            b_N: As :meth:`VereshchaginSolver.solve`.

        Returns:
            FrictionResult.
        """
        return self._solve(q, qd, tau, base_acceleration, external_wrenches, A_N, b_N)

    def _solve_box(self, q, qd, tau, a0, fext, A, b):
        res, mu, stationary, stick, qdd0, G, ok = self.solver.kernel.friction(
            q, qd, tau, a0, fext, A, b, self.breakaway, self.eps)
        if not ok:                    # the active set failed its KKT check: general QP
            return self._solve_qp(q, qd, tau, a0, fext, A, b)
        return FrictionResult(mu=mu, stationary=stationary, stick=stick, qdd=res.qdd,
                              result=res, qdd0=qdd0, G=G, gauss=res.gauss)

    def _solve_qp(self, q, qd, tau, a0, fext, A, b):
        joints = np.flatnonzero(self.stationary(qd))
        base, Gfull, combine = self.solver.solve_with_sensitivity(
            q, qd, tau, joints=joints, base_acceleration=a0, external_wrenches=fext, A_N=A,
            b_N=b)
        k = joints.size
        q0 = base.qdd[joints]
        G = Gfull[joints]
        G = 0.5 * (G + G.T)
        f = self.breakaway[joints]
        mu_s = self.box_qp(G, q0, f) if k else np.zeros(0)
        res = combine(mu_s, gauss=True)
        mu = np.zeros(self.solver.n)
        mu[joints] = mu_s
        stationary = np.zeros(self.solver.n, dtype=bool)
        stationary[joints] = True
        stick = np.zeros(self.solver.n, dtype=bool)
        # strictly inside the box <=> zero acceleration (KKT); tolerance relative to f
        stick[joints] = np.abs(mu_s) < f * (1.0 - 1e-7)
        return FrictionResult(mu=mu, stationary=stationary, stick=stick, qdd=res.qdd,
                              result=res, qdd0=base.qdd, G=G, gauss=res.gauss)

    def box_qp(self, G, g, f):
        """Argmin ½ μᵀ G μ + gᵀ μ  s.t.  −f ≤ μ ≤ f (G symmetric PSD), polished exactly.

        Solved with this solver's ``qp_solver`` (daqp or proxsuite), then polished.

        Args:
            G: (k, k) symmetric positive semidefinite matrix.
            g: (k,) linear term.
            f: (k,) half-widths of the box, ≥ 0.
        """
        return _polish(G, g, f, self._box_qp_raw(G, g, f))

    def _box_qp_raw(self, G, g, f):
        """The QP solver's answer, before polishing (SolverError if it fails)."""
        # each QP library is imported when chosen (qp_solver), as in ifc_spg.cascade
        k = g.size
        if self.qp_solver == 'daqp':
            import daqp
            # simple bounds only (A has no rows); eps_prox < 0 regularizes a singular G
            x, _, exitflag, _ = daqp.solve(np.ascontiguousarray(G), np.ascontiguousarray(g),
                                           np.zeros((0, k)), np.ascontiguousarray(f),
                                           np.ascontiguousarray(-f), eps_prox=-1.0)
            if exitflag < 1:
                raise SolverError(f'daqp failed on the friction QP (exitflag {exitflag}); '
                                  "try qp_solver='proxsuite'")
            return np.clip(np.asarray(x, dtype=float), -f, f)
        from proxsuite import proxqp
        qp = self._qp_cache.get(k)
        if qp is None:
            qp = proxqp.dense.QP(k, 0, 0, True)
            qp.settings.eps_abs = 1e-12
            qp.settings.eps_rel = 0.0
            qp.settings.max_iter = 10000
            qp.settings.verbose = False
            qp.init(G, g, None, None, None, None, None, -f, f)
            self._qp_cache[k] = qp
        else:
            qp.update(G, g, None, None, None, None, None, -f, f)
        qp.solve()
        st = qp.results.info.status
        if st != proxqp.PROXQP_SOLVED:
            raise SolverError(f'proxsuite failed on the friction QP (status {st})')
        return np.clip(np.asarray(qp.results.x, dtype=float), -f, f)

    # -- the report's sampling method (reference) ------------------------------------------
    def solve_sampling(self, q, qd, tau=None, *, samples=21, **kwargs):
        """The report's method: full solver run per grid point of μ, keep the maximum of Z.

        Args:
            q: Configuration (pinocchio nq).
            qd: Joint velocities.
            tau: Feed-forward torques.
            samples: Grid points per stationary joint (the grid includes ±f_j; an odd
                number includes 0). Cost: samples**k solver runs.
            **kwargs: ``base_acceleration``, ``external_wrenches``, ``A_N``, ``b_N``.
        """
        if int(samples) < 2:
            raise ParameterError(f'samples must be >= 2, got {samples}')
        joints = np.flatnonzero(self.stationary(qd))
        n = self.solver.n
        tau = np.zeros(n) if tau is None else np.asarray(tau, dtype=float)
        grids = [np.linspace(-f, f, int(samples)) for f in self.breakaway[joints]]
        pts = np.array(list(itertools.product(*grids))) if grids else np.zeros((1, 0))
        Z = np.empty(len(pts))
        Q = np.empty((len(pts), n))
        for s, mu_s in enumerate(pts):
            t = tau.copy()
            t[joints] += mu_s
            r = self.solver.solve(q, qd, t, gauss=True, **kwargs)
            Z[s] = r.gauss
            Q[s] = r.qdd
        best = int(np.argmax(Z))
        mu = np.zeros(n)
        mu[joints] = pts[best]
        return SamplingResult(mu=mu, qdd=Q[best], gauss=float(Z[best]), samples=pts,
                              gauss_samples=Z, qdd_samples=Q, joints=joints)
