"""Benchmark of the Popov-Vereshchagin solver (not a test; numbers for the docs).

1. O(n): time per call on random chains of 2...64 DoF, linear fit (slope, R²).
2. iiwa-like 7-DoF arm: solver (free and with 3 constraints) next to pinocchio ABA,
   same run: median, p99, max per call.
3. Static friction, 3 stationary joints: exact QP method vs the report's sampling with
   21 samples per joint (9261 solver runs).
4. KDL's C++ ``ChainHdSolver_Vereshchagin`` side by side (where liborocos-kdl-dev is
   installed; the timing program is built at run time, see :mod:`benchmarks.kdl`):
   the iiwa 14 and a 17-DoF chain, free and with 1 and 3 constraints; ours in C and in
   numpy, KDL and pinocchio ABA, same states, same run; the ratio ours (C) / KDL and the
   largest difference of KDL's q̈ from ours (same chain given to both).

Run: ``ifc-spg dynamics bench [--quick] [--json FILE]`` or
``python -m benchmarks.dynamics_bench``.
"""

import argparse
import functools
import json
import sys
import time

import numpy as np
import pinocchio as pin

from benchmarks import kdl
from ifc_spg.dynamics import native
from ifc_spg.dynamics.models import iiwa_like_model, random_chain_model
from ifc_spg.dynamics.static_friction import StaticFrictionSolver
from ifc_spg.dynamics.vereshchagin import VereshchaginSolver
from ifc_spg.model import RobotModel

__all__ = ['main']


def _time_calls(fn, states, repeat):
    """Per-call wall time in [us] over ``repeat`` passes through ``states``."""
    out = []
    for _ in range(repeat):
        for s in states:
            t0 = time.perf_counter_ns()
            fn(*s)
            out.append(time.perf_counter_ns() - t0)
    return np.array(out) / 1e3


def _stats(t):
    return {'median_us': float(np.median(t)), 'p99_us': float(np.percentile(t, 99)),
            'max_us': float(np.max(t)), 'calls': int(t.size)}


def _states(rng, model, count):
    """``count`` states (q, qdot, tau), all from ``rng``.

    pinocchio's ``randomConfiguration`` draws from its own global generator: seeded from
    ``rng``, a seeded run repeats.
    """
    lo, hi = -np.pi * np.ones(model.nq), np.pi * np.ones(model.nq)
    pin.seed(int(rng.integers(2**31 - 1)))
    return [(pin.randomConfiguration(model, lo, hi), rng.normal(size=model.nv),
             rng.normal(size=model.nv)) for _ in range(count)]


def bench_scaling(rng, dofs, calls):
    """Median time per call vs DoF with a least-squares line t = a + b n."""
    rows = []
    for n in dofs:
        model = random_chain_model(rng, n)
        solver = VereshchaginSolver(model, tip_frame='tip')
        states = _states(rng, model, 20)
        solver.solve(*states[0])
        t = _time_calls(lambda q, v, tau, solver=solver: solver.solve(q, v, tau), states,
                        max(1, calls // 20))
        rows.append((n, float(np.median(t))))
    n = np.array([r[0] for r in rows], dtype=float)
    t = np.array([r[1] for r in rows])
    b, a = np.polyfit(n, t, 1)
    r2 = 1.0 - np.sum((t - (a + b * n)) ** 2) / np.sum((t - t.mean()) ** 2)
    return {'dof': n.astype(int).tolist(), 'median_us': t.tolist(), 'slope_us_per_dof': float(b),
            'intercept_us': float(a), 'r2': float(r2)}


def bench_iiwa(rng, calls, model=None, label='iiwa_like'):
    """Solver vs pinocchio ABA on the 7-DoF arm (same states, same run)."""
    model = iiwa_like_model() if model is None else model
    data = model.createData()
    solver = VereshchaginSolver(model)
    states = _states(rng, model, 50)
    rep = max(1, calls // 50)
    A = np.eye(6)[:, [0, 1, 2]]
    b = np.zeros(3)
    res = {'model': label, 'dof': model.nv}
    res['pinocchio_aba'] = _stats(_time_calls(lambda q, v, t: pin.aba(model, data, q, v, t),
                                              states, rep))
    res['vereshchagin_free'] = _stats(_time_calls(lambda q, v, t: solver.solve(q, v, t),
                                                  states, rep))
    res['vereshchagin_3_constraints'] = _stats(_time_calls(
        lambda q, v, t: solver.solve(q, v, t, A_N=A, b_N=b), states, rep))
    res['ratio_median_free_vs_aba'] = (res['vereshchagin_free']['median_us']
                                       / res['pinocchio_aba']['median_us'])
    return res


def bench_friction(rng, problems, samples=21, calls=500):
    """Exact QP vs sampling (``samples`` per joint) with 3 stationary joints."""
    rows = []
    for _ in range(problems):
        model = iiwa_like_model()
        fs = StaticFrictionSolver(VereshchaginSolver(model, tip_frame='tool'),
                                  rng.uniform(1.0, 5.0, 7))
        pin.seed(int(rng.integers(2**31 - 1)))  # pinocchio's global generator, from rng
        q = pin.randomConfiguration(model, -np.pi * np.ones(7), np.pi * np.ones(7))
        qd = rng.normal(size=7)
        qd[rng.choice(7, 3, replace=False)] = 0.0
        tau = rng.normal(size=7) * 5
        fs.solve(q, qd, tau)                       # warm-up (imports, QP object)
        t_exact = _time_calls(lambda fs=fs, q=q, qd=qd, tau=tau: fs.solve(q, qd, tau), [()],
                              calls)
        t0 = time.perf_counter()
        ref = fs.solve_sampling(q, qd, tau, samples=samples)
        t_samp = time.perf_counter() - t0
        ex = fs.solve(q, qd, tau)
        rows.append({'exact_median_us': float(np.median(t_exact)),
                     'exact': _stats(t_exact),
                     'sampling_s': t_samp, 'speedup': t_samp * 1e6 / float(np.median(t_exact)),
                     'gauss_exact': ex.gauss, 'gauss_sampling': ref.gauss,
                     'mu_exact': ex.mu.tolist(), 'mu_sampling': ref.mu.tolist()})
    return {'samples_per_joint': samples, 'runs_per_sampling': samples ** 3, 'problems': rows,
            'min_speedup': min(r['speedup'] for r in rows)}


def _kdl_chains():
    """The chains of the KDL comparison: (label, model, tip frame)."""
    chains = []
    try:
        rm = RobotModel.from_config('lbr_iiwa14')
        chains.append(('lbr_iiwa14', rm.model, rm.frames['tool']))
    except Exception as exc:  # noqa: BLE001 - optional model from another module
        print(f'  (RobotModel lbr_iiwa14 not available: {type(exc).__name__}: {exc}; '
              'using the iiwa-like model)')
        chains.append(('iiwa_like', iiwa_like_model(), 'tool'))
    chains.append(('random17', random_chain_model(np.random.default_rng(17), 17), 'tip'))
    return chains


def bench_kdl(rng, calls):
    """Ours (C, numpy), KDL and pinocchio ABA on the same chains and states (section 4)."""
    ok, why = kdl.available()
    exe = None
    if ok:
        try:
            exe = kdl.build()
        except RuntimeError as exc:
            why = str(exc)
    out = {'kdl': exe is not None, 'kdl_missing': None if exe else why, 'rows': []}
    eye = np.eye(6)
    for label, model, tip in _kdl_chains():
        data = model.createData()
        solvers = {'numpy': VereshchaginSolver(model, tip_frame=tip, kernel='numpy')}
        if native.NativeKernel is not None:
            solvers['c'] = VereshchaginSolver(model, tip_frame=tip, kernel='native')
        chain = solvers['numpy'].chain
        states = _states(rng, model, 50)
        rep = max(1, calls // 50)
        aba = _stats(_time_calls(functools.partial(pin.aba, model, data), states, rep))
        a0 = -np.asarray(model.gravity.vector, dtype=float)
        for m, A in ((0, None), (1, eye[:, [2]]), (3, eye[:, :3])):
            b = None if A is None else np.zeros(m)
            row = {'chain': label, 'dof': model.nv, 'constraints': m, 'pinocchio_aba': aba}
            for key, solver in solvers.items():
                row[f'ours_{key}'] = _stats(_time_calls(
                    lambda q, v, t, solver=solver, A=A, b=b: solver.solve(q, v, t, A_N=A, b_N=b),
                    states, rep if key == 'c' else max(1, rep // 4)))
            if exe is not None:
                ours = np.array([solvers['numpy'].solve(q, v, t, A_N=A, b_N=b).qdd
                                 for q, v, t in states])
                qdd, t_kdl = kdl.run(exe, chain, [(chain.joint_angles(q), v, t)
                                                  for q, v, t in states],
                                     base_acceleration=a0, A_N=A, b_N=b, repeat=rep)
                row['kdl'] = _stats(t_kdl)
                row['kdl_max_qdd_diff'] = float(np.max(np.abs(qdd - ours)))
                # relative to each state's largest acceleration (a near-singular constrained
                # state has accelerations of 1e3 rad/s^2 and more; round-off scales with them)
                row['kdl_max_qdd_rel_diff'] = float(np.max(
                    np.abs(qdd - ours).max(axis=1) / (1.0 + np.abs(qdd).max(axis=1))))
                if 'ours_c' in row:
                    row['ratio_c_vs_kdl'] = row['ours_c']['median_us'] / row['kdl']['median_us']
            out['rows'].append(row)
    return out


def print_kdl(res):
    """Print section 4: per chain and constraint count, median / p99 / max per call."""
    print("KDL's C++ ChainHdSolver_Vereshchagin side by side (same chains, same states):")
    if not res['kdl']:
        print(f'  KDL: not run: {res["kdl_missing"]}')
    cols = (('ours_c', 'ours (C)'), ('ours_numpy', 'ours (numpy)'), ('kdl', 'KDL (C++, -O2)'),
            ('pinocchio_aba', 'pinocchio ABA'))
    for r in res['rows']:
        print(f'  {r["chain"]} ({r["dof"]} DoF), {r["constraints"]} constraints, per call [us]'
              '     median      p99      max')
        for key, name in cols:
            if key in r:
                s = r[key]
                note = '   (free motion: ABA has no constraints)' if key == 'pinocchio_aba' \
                    and r['constraints'] else ''
                print(f'    {name:34s} {s["median_us"]:8.2f} {s["p99_us"]:8.2f} '
                      f'{s["max_us"]:8.2f}{note}')
        if 'ratio_c_vs_kdl' in r:
            print(f'    median ratio ours (C) / KDL: {r["ratio_c_vs_kdl"]:.2f}x   '
                  f'max |qdd - qdd_KDL| = {r["kdl_max_qdd_diff"]:.1e} '
                  f'(relative to 1 + the state\'s max |qdd_KDL|: {r["kdl_max_qdd_rel_diff"]:.1e})')
    print('  summary, median per call [us]:')
    print('    chain         DoF  constr   ours C  ours numpy      KDL  pin. ABA  C/KDL')
    for r in res['rows']:
        med = {k: (f'{r[k]["median_us"]:8.2f}' if k in r else '       -') for k, _ in cols}
        ratio = f'{r["ratio_c_vs_kdl"]:6.2f}x' if 'ratio_c_vs_kdl' in r else '      -'
        print(f'    {r["chain"]:12s} {r["dof"]:4d} {r["constraints"]:7d} {med["ours_c"]}'
              f'    {med["ours_numpy"]} {med["kdl"]}  {med["pinocchio_aba"]} {ratio}')


def main(argv=None):
    """Run the benchmark and print a summary; ``--json FILE`` also writes all numbers."""
    parser = argparse.ArgumentParser(prog='ifc-spg dynamics bench', description=__doc__)
    parser.add_argument('--quick', action='store_true', help='fewer calls (smoke run)')
    parser.add_argument('--json', metavar='FILE', help='write the results as JSON')
    parser.add_argument('--seed', type=int, default=0)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    calls = 200 if args.quick else 2000
    dofs = [2, 4, 8, 16, 32, 64] if args.quick else [2, 4, 6, 8, 12, 16, 24, 32, 40, 48, 56, 64]
    out = {'numpy': np.__version__, 'pinocchio': pin.__version__,
           'kernel': native.describe()}
    print(f'dynamics kernel: {native.describe()}')
    out['scaling'] = sc = bench_scaling(rng, dofs, calls)
    print('time per call vs DoF (random chains, free motion):')
    for n, t in zip(sc['dof'], sc['median_us']):
        print(f'  n = {n:3d}: {t:8.1f} us')
    print(f'  linear fit: t = {sc["intercept_us"]:.1f} us + {sc["slope_us_per_dof"]:.2f} us/DoF'
          f' * n,  R^2 = {sc["r2"]:.4f}')
    out['iiwa'] = [bench_iiwa(rng, calls)]
    try:
        rm = RobotModel.from_config('lbr_iiwa14')
        out['iiwa'].append(bench_iiwa(rng, calls, rm.model, 'RobotModel lbr_iiwa14'))
    except Exception as exc:  # noqa: BLE001 - optional model from another module
        print(f'  (RobotModel lbr_iiwa14 not available: {type(exc).__name__}: {exc})')
    for r in out['iiwa']:
        print(f'{r["model"]} ({r["dof"]} DoF), per call [us]   median     p99     max')
        for key in ('pinocchio_aba', 'vereshchagin_free', 'vereshchagin_3_constraints'):
            s = r[key]
            print(f'  {key:28s} {s["median_us"]:8.1f} {s["p99_us"]:8.1f} {s["max_us"]:8.1f}')
        print(f'  median ratio solver / ABA: {r["ratio_median_free_vs_aba"]:.0f}x')
    out['friction'] = fr = bench_friction(rng, 1 if args.quick else 3,
                                          calls=100 if args.quick else 1000)
    print('static friction, 3 stationary joints (iiwa-like), exact solve per call [us]:')
    for r in fr['problems']:
        e = r['exact']
        print(f'  exact median {e["median_us"]:.1f}, p99 {e["p99_us"]:.1f}, max '
              f'{e["max_us"]:.1f}; sampling ({fr["runs_per_sampling"]} runs) '
              f'{r["sampling_s"]:.2f} s -> {r["speedup"]:.0f}x faster; '
              f'Z exact {r["gauss_exact"]:.6g} >= Z sampling {r["gauss_sampling"]:.6g}')
    out['kdl'] = bench_kdl(rng, calls if args.quick else 5 * calls)
    print_kdl(out['kdl'])
    if args.json:
        with open(args.json, 'w', encoding='utf-8') as fh:
            json.dump(out, fh, indent=2)
        print(f'wrote {args.json}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
