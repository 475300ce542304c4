"""KDL's C++ ``ChainHdSolver_Vereshchagin`` on our chains, for the benchmark and a cross-check.

Where ``liborocos-kdl-dev`` is installed (Debian/Ubuntu: ``apt-get install
liborocos-kdl-dev``), :func:`build` compiles ``kdl_bench.cpp`` (next to this file) with
``g++ -O2`` into a cache directory, once per source version; :func:`run` feeds it a chain,
constraints and states and returns KDL's q̈ and its wall time per call, measured in C++.

The chain given to KDL is ours, converted (:func:`kdl_segments`): KDL attaches a segment's
joint at its root and expresses its inertia in its *tip* frame, so segment i rotates (or
slides) about axis_i at its root and ends at the placement of joint i + 1 (the tip frame
for the last one), with the inertia of our segment i moved into that tip frame; the
placement of joint 0 is KDL's base frame (KDL's solver takes no fixed segments), so the
base acceleration and A_N are turned into it. The bench prints the largest difference
of KDL's q̈ from ours, which checks this conversion.
"""

import hashlib
import os
import shutil
import subprocess
import tempfile

import numpy as np

__all__ = ['available', 'build', 'kdl_segments', 'run', 'run_segments']

_SOURCE = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'kdl_bench.cpp')
_HEADER = 'kdl/chainhdsolver_vereshchagin.hpp'
_INCLUDE_DIRS = ('/usr/include', '/usr/local/include', '/opt/ros/jazzy/include',
                 '/opt/ros/humble/include')


def _find_include(rel):
    roots = list(_INCLUDE_DIRS)
    if os.environ.get('CONDA_PREFIX'):
        roots.insert(0, os.path.join(os.environ['CONDA_PREFIX'], 'include'))
    for root in roots:
        if os.path.isfile(os.path.join(root, rel)):
            return root
    return None


def available():
    """``(True, '')`` when KDL can be benchmarked here, else ``(False, why)``."""
    if not os.path.isfile(_SOURCE):
        return False, f'the timing program source {_SOURCE} is not installed'
    if _find_include(_HEADER) is None:
        return False, (f'KDL not found ({_HEADER} is in none of {", ".join(_INCLUDE_DIRS)}); '
                       'install it with: apt-get install liborocos-kdl-dev')
    if shutil.which('g++') is None:
        return False, 'g++ not found (needed to build the KDL timing program)'
    if _find_include('eigen3/Eigen/Core') is None:
        return False, 'Eigen 3 headers not found (libeigen3-dev), needed by KDL'
    return True, ''


def build(cache_dir=None):
    """Compile the timing program (once per source version) and return its path.

    Raises:
        RuntimeError: KDL is not available or the compiler failed (message says why).
    """
    ok, why = available()
    if not ok:
        raise RuntimeError(why)
    inc = _find_include(_HEADER)
    eig = os.path.join(_find_include('eigen3/Eigen/Core'), 'eigen3')
    flags = ['-O2', '-DNDEBUG', '-std=c++14', f'-I{inc}', f'-I{eig}']
    with open(_SOURCE, 'rb') as fh:
        digest = hashlib.sha256(fh.read() + ' '.join(flags).encode()).hexdigest()[:16]
    if cache_dir is None:
        cache_dir = os.path.join(os.environ.get('XDG_CACHE_HOME')
                                 or os.path.join(os.path.expanduser('~'), '.cache'), 'ifc_spg')
    exe = os.path.join(cache_dir, f'kdl_bench-{digest}')
    if os.path.isfile(exe) and os.access(exe, os.X_OK):
        return exe
    os.makedirs(cache_dir, exist_ok=True)
    tmp = tempfile.mkdtemp(dir=cache_dir)
    try:
        out = os.path.join(tmp, 'kdl_bench')
        cmd = ['g++', *flags, _SOURCE, '-o', out, '-lorocos-kdl']
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if proc.returncode != 0:
            raise RuntimeError(f'building the KDL timing program failed: {" ".join(cmd)}\n'
                               f'{proc.stderr.strip()[-2000:]}')
        os.replace(out, exe)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return exe


def kdl_segments(chain):
    """Our chain as KDL segments, and the KDL base frame in ours.

    KDL's Vereshchagin solver (1.5) does not take fixed segments, so the placement of joint
    0 becomes KDL's base: segment i rotates (or slides) about axis_i at its root and ends at
    the placement of joint i + 1 (the tip frame for the last one).

    Returns:
        ``(rows, R0, p0)``: rows (type, axis, rotor inertia, f_tip R, f_tip p, mass, cog, I)
        with type 1 (revolute) or 2 (prismatic), f_tip and the inertia (cog, rotational
        inertia about it) in the segment's tip frame; R0, p0 the KDL base in our base frame.
    """
    n = chain.n
    rows = []
    for i in range(n):
        if i + 1 < n:
            Rt, pt = chain.R_parent[i + 1], chain.p_parent[i + 1]
        else:
            Rt, pt = chain.tip_placement[:3, :3], chain.tip_placement[:3, 3]
        cog = Rt.T @ (chain.com[i] - pt)
        Ic = Rt.T @ chain.inertia_com[i] @ Rt
        rows.append((1 if chain.revolute[i] else 2, chain.axis[i], float(chain.armature[i]),
                     Rt, pt, float(chain.mass[i]), cog, Ic))
    return rows, chain.R_parent[0], chain.p_parent[0]


def _fmt(values):
    return ' '.join(repr(float(v)) for v in np.asarray(values, dtype=float).reshape(-1))


def run(exe, chain, states, *, base_acceleration, A_N=None, b_N=None, repeat=20):
    """Run KDL on ``states`` [(joint angles, qd, tau), ...] with the constraints A_N, b_N.

    Without constraints KDL gets one all-zero unit constraint force (its solver needs
    nc >= 1; 𝓛 = 0 then gives ν = 0, free motion).

    Returns:
        ``(qdd, times_us)``: KDL's q̈ per state, shape (len(states), n), and the wall time
        of each of the ``repeat * len(states)`` timed calls in [us].
    """
    A = np.zeros((6, 0)) if A_N is None else np.asarray(A_N, dtype=float).reshape(6, -1)
    segs, R0, p0 = kdl_segments(chain)
    # into KDL's base (R0, p0): the base acceleration moves to p0; A_N (tip origin, base
    # axes) only turns
    a0 = np.asarray(base_acceleration, dtype=float)
    a0 = np.concatenate((R0.T @ (a0[:3] + np.cross(a0[3:], p0)), R0.T @ a0[3:]))
    A = np.vstack((R0.T @ A[:3], R0.T @ A[3:]))
    return run_segments(exe, segs, states, base_acceleration=a0, A_N=A, b_N=b_N,
                        repeat=repeat)


def run_segments(exe, segs, states, *, base_acceleration, A_N=None, b_N=None, repeat=20):
    """:func:`run` on KDL segments as given: rows as :func:`kdl_segments` returns them.

    Each row is ``(type, axis, rotor inertia, f_tip R, f_tip p, mass, cog, I)`` in KDL's own
    convention (the cog and the rotational inertia about it in the segment's *tip* frame),
    the base acceleration and A_N in KDL's base frame.
    """
    A = np.zeros((6, 0)) if A_N is None else np.asarray(A_N, dtype=float).reshape(6, -1)
    b = np.zeros(A.shape[1]) if b_N is None else np.asarray(b_N, dtype=float).reshape(-1)
    if A.shape[1] == 0:     # KDL needs nc >= 1: free motion is one all-zero constraint
        A, b = np.zeros((6, 1)), np.zeros(1)
    a0 = np.asarray(base_acceleration, dtype=float)
    lines = [f'{len(segs)} {A.shape[1]} {len(states)} {int(repeat)}']
    for kind, ax, rotor, R, p, m, c, Ic in segs:
        Ic = np.asarray(Ic, dtype=float)
        lines.append(f'{kind} {_fmt(ax)} {rotor!r} {_fmt(R)} {_fmt(p)} {m!r} {_fmt(c)} '
                     f'{_fmt([Ic[0, 0], Ic[1, 1], Ic[2, 2], Ic[0, 1], Ic[0, 2], Ic[1, 2]])}')
    lines.append(f'{_fmt(a0)} {_fmt(A)} {_fmt(b)}')
    for th, qd, tau in states:
        lines.append(f'{_fmt(th)} {_fmt(qd)} {_fmt(tau)}')
    proc = subprocess.run([exe], input='\n'.join(lines) + '\n', capture_output=True, text=True,
                          check=False)
    if proc.returncode != 0:
        raise RuntimeError(f'the KDL timing program failed ({proc.returncode}): '
                           f'{proc.stderr.strip()}')
    qdd, ns = [], None
    for line in proc.stdout.splitlines():
        head, _, rest = line.partition(' ')
        if head == 'qdd':
            qdd.append(np.array(rest.split(), dtype=float))
        elif head == 'ns':
            ns = np.array(rest.split(), dtype=float)
    if ns is None:
        raise RuntimeError(f'the KDL timing program printed no timings: {proc.stdout[-200:]!r}')
    return np.array(qdd), ns / 1e3
