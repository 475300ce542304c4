"""``ifc-spg dynamics``: run the Popov-Vereshchagin solver with static friction.

Usage::

    ifc-spg dynamics [scenarios] [--plot DIR] [--samples N]   # the report's Ch. 6 scenarios
    ifc-spg dynamics solve PROBLEM.yaml [--plot DIR] [--samples N]
    ifc-spg dynamics bench [--quick] [--json FILE]   # timing, benchmarks/dynamics_bench.py

For each problem it prints q̈, ν and τ_control without friction, then the static-friction
solution: μ*, which joints stick, q̈(μ*) and the resulting joint torques, next to the
report's sampling method as a reference. ``--plot DIR`` writes the acceleration energy
Z(μ), q̈(μ) and the resulting torque over μ (the report's Figs. 6.2-6.7) as PNG files.
The problem-file format is in :mod:`ifc_spg.dynamics.scenarios`.
"""

import argparse
from collections.abc import Sequence
import os
import sys

import numpy as np

from ifc_spg.cli.bench import benchmark_module
from ifc_spg.dynamics.scenarios import external_joint_torques, load_problem, report_problems
from ifc_spg.errors import IfcSpgError

__all__ = ['main']


def _fmt(x):
    return np.array2string(np.asarray(x, dtype=float), precision=6, suppress_small=True,
                           max_line_width=99, floatmode='maxprec')


def run_problem(prob, *, samples=21, plot_dir=None, out=None):
    """Solve one :class:`~ifc_spg.dynamics.scenarios.Problem` and print the results.

    Returns:
        dict with the plain result, the friction result and the sampling result.
    """
    solver = prob.solver()
    plain = solver.solve(prob.q, prob.qd, prob.tau, **prob.kwargs)
    out = sys.stdout if out is None else out
    p = lambda *a: print(*a, file=out)  # noqa: E731
    p(f'== {prob.name}' + (f': {prob.expected}' if prob.expected else ''))
    p(f'  joints          {", ".join(solver.chain.joint_names)}')
    p(f'  qdd             {_fmt(plain.qdd)}')
    p(f'  nu              {_fmt(plain.nu)}')
    p(f'  tau_control     {_fmt(plain.tau_control)}')
    if plain.singular:
        p(f'  WARNING: constraint coupling matrix is rank-deficient (rank {plain.rank} < '
          f'{plain.nu.size}); damped solution, residual {_fmt(plain.constraint_residual)}')
    out_d = {'plain': plain, 'friction': None, 'sampling': None}
    if prob.breakaway is None:
        return out_d
    fs = prob.friction_solver()
    fr = fs.solve(prob.q, prob.qd, prob.tau, **prob.kwargs)
    tau_ext = external_joint_torques(prob.model, prob.q, prob.kwargs.get('external_wrenches'))
    p(f'  breakaway f     {_fmt(fs.breakaway)}   (at rest: |qd| <= {fs.eps:g})')
    p(f'  stationary      {fr.stationary.astype(int)}')
    p(f'  mu* (exact QP)  {_fmt(fr.mu)}')
    p(f'  stick           {fr.stick.astype(int)}')
    p(f'  qdd(mu*)        {_fmt(fr.qdd)}')
    p(f'  nu(mu*)         {_fmt(fr.result.nu)}')
    p(f'  tau_control     {_fmt(fr.result.tau_control)}   (feed-forward + friction + '
      'constraint)')
    p(f'  resulting torque {_fmt(prob.tau + fr.mu + tau_ext)}   (tau + mu + J^T F_ext)')
    p(f'  Z(mu*)          {fr.gauss:.9g}')
    k = int(fr.stationary.sum())
    if k and samples:
        if samples ** k > 200000:
            p(f'  sampling reference skipped ({samples}^{k} runs)')
        else:
            sr = fs.solve_sampling(prob.q, prob.qd, prob.tau, samples=samples, **prob.kwargs)
            out_d['sampling'] = sr
            p(f'  sampling ref.   mu = {_fmt(sr.mu)}  Z = {sr.gauss:.9g}  '
              f'({samples}^{k} = {samples ** k} solver runs)')
            if plot_dir:
                for f in _plot(prob, fr, sr, tau_ext, plot_dir):
                    p(f'  plot            {f}')
    out_d['friction'] = fr
    return out_d


def _plot(prob, fr, sr, tau_ext, plot_dir):
    """Figures like the report's 6.2-6.7 (1 stationary joint), a contour for 2."""
    import matplotlib  # heavy, and only for --plot
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    os.makedirs(plot_dir, exist_ok=True)
    joints = sr.joints
    files = []
    if joints.size == 1:
        j = joints[0]
        mu = sr.samples[:, 0]
        order = np.argsort(mu)
        net = prob.tau[j] + mu + tau_ext[j]
        for tag, y, label in (('gauss', sr.gauss_samples, 'acceleration energy Z [Nm/s$^2$]'),
                              ('qdd', sr.qdd_samples[:, j], f'$\\ddot q_{j + 1}$ [rad/s$^2$]'),
                              ('torque', net, f'resulting torque joint {j + 1} [Nm]')):
            fig, ax = plt.subplots(figsize=(5, 3.5))
            ax.plot(mu[order], y[order], '.-', label='sampling (report)')
            star = {'gauss': fr.gauss, 'qdd': fr.qdd[j],
                    'torque': prob.tau[j] + fr.mu[j] + tau_ext[j]}[tag]
            ax.plot([fr.mu[j]], [star], 'r*', ms=12, label=f'exact $\\mu^*$ = {fr.mu[j]:.3g}')
            ax.set_xlabel(f'friction torque $\\mu_{j + 1}$ [Nm]')
            ax.set_ylabel(label)
            ax.set_title(prob.name)
            ax.grid(True)
            ax.legend()
            fig.tight_layout()
            f = os.path.join(plot_dir, f'{prob.name}_{tag}.png')
            fig.savefig(f, dpi=100)
            plt.close(fig)
            files.append(f)
    elif joints.size == 2:
        s = int(round(np.sqrt(len(sr.samples))))
        fig, ax = plt.subplots(figsize=(5, 4))
        cs = ax.contourf(sr.samples[:, 0].reshape(s, s), sr.samples[:, 1].reshape(s, s),
                         sr.gauss_samples.reshape(s, s), 20)
        fig.colorbar(cs, label='Z [Nm/s$^2$]')
        ax.plot(fr.mu[joints[0]], fr.mu[joints[1]], 'r*', ms=12, label='exact $\\mu^*$')
        ax.set_xlabel(f'$\\mu_{joints[0] + 1}$ [Nm]')
        ax.set_ylabel(f'$\\mu_{joints[1] + 1}$ [Nm]')
        ax.legend()
        fig.tight_layout()
        f = os.path.join(plot_dir, f'{prob.name}_gauss.png')
        fig.savefig(f, dpi=100)
        plt.close(fig)
        files.append(f)
    return files


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ifc-spg dynamics``; returns the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == 'bench':
        bench = benchmark_module('dynamics_bench', 'ifc-spg dynamics bench')
        return 2 if bench is None else int(bench.main(argv[1:]) or 0)
    parser = argparse.ArgumentParser(
        prog='ifc-spg dynamics', description=__doc__.split('\n\n')[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog='commands: scenarios (default) | solve PROBLEM.yaml | bench')
    parser.add_argument('command', nargs='?', default='scenarios',
                        choices=('scenarios', 'solve'))
    parser.add_argument('problem', nargs='?', help='problem file (YAML) for "solve"')
    parser.add_argument('--plot', metavar='DIR', help='write Z(mu), qdd(mu), torque(mu) PNGs')
    parser.add_argument('--samples', type=int, default=21,
                        help='sampling reference: grid points per stationary joint (0: off)')
    args = parser.parse_args(argv)
    try:
        if args.command == 'scenarios':
            problems = report_problems() + report_problems(implemented=True)
        else:
            if not args.problem:
                parser.error('solve needs a problem file: ifc-spg dynamics solve FILE.yaml')
            problems = [load_problem(args.problem)]
        for prob in problems:
            run_problem(prob, samples=args.samples, plot_dir=args.plot)
    except IfcSpgError as exc:
        print(f'ifc-spg dynamics: error: {exc}', file=sys.stderr)
        return 2
    return 0


if __name__ == '__main__':
    sys.exit(main())
