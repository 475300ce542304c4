"""Soak benchmark: a long lockstep run that must stay safe, lean and steady.

    python -m benchmarks.soak [--hours 1] [--minutes M] [--quick] [--robot lbr_iiwa14]
                                 [--json F]

The MuJoCo simulation (:class:`sim_bridge.simulation.Simulation`, free scene, 1 kHz
physics) and the SPG node's logic (:class:`~ifc_spg.node.core.SpgRunner`) run in lockstep
in one process, one SPG tick per 2 ms of simulated time, no DDS. Every ``--period``
seconds (default 10) of simulated time the next task stack of a fixed cycle is sent
(joint targets, a Cartesian circle, a sine, a Cartesian hold with joint torque and posture
levels, a contradictory pair), and every 7 s a short push disturbs the robot. Every
command goes through :class:`CommandChecker` (the guarantees of README.md "What is always true").

Reported (JSON on stdout, also to ``--json``): ticks, simulated and wall time, exceptions,
limit violations (with the first few described), resident memory (RSS) at 10 % of the run
and at the end and its growth in MB, and the SPG tick time p50/p99 [ms] over the first
and the last 10 % of the ticks. The exit code is 1 when there was an exception, a
violation or RSS growth >= 20 MB, else 0. ``--quick`` runs 60 s of simulated time.

:class:`CommandChecker` is also what the robustness tests use to check every command.
"""

import argparse
import json
import math
import os
import sys
import time
import traceback

import numpy as np

from ifc_spg.limits import joint_velocity_bounds
from ifc_spg.node.config import SpgConfig
from ifc_spg.node.core import SpgRunner

__all__ = ['CommandChecker', 'STACKS', 'rss_mb', 'run_soak', 'main']

# Tolerances of the checks: round-off of the clip/step arithmetic, not physics.
POS_TOL = 1e-9      # [rad] q_v - q_v_prev vs dT qdot_v
VEL_TOL = 1e-9      # [rad/s] relative+absolute slack on |qdot_v| <= v_max
ACC_TOL = 1e-7      # [rad/s] on |qdot_v - qdot_v_prev| <= a_max dT
TANK_EMPTY = 1e-9   # [J] a tank at most this full is "empty"


class CommandChecker:
    """Checks each command against the limit guarantees (README.md "What is always true", G1).

    Per command: finite; q_min <= q_v <= q_max; |qdot_v| <= v_max; within a session
    (no restart between two commands) q_v - q_v_prev = dT qdot_v and
    |qdot_v - qdot_v_prev| <= a_max dT, except on a joint where the harder stop is forced:
    (a) position safety: the acceleration box lies outside the position/velocity box of
    q_v_prev and qdot_v sits on that box's nearest bound, or (b) the joint's PSPM tank is
    empty after the tick (<= 1e-9 J: the step spent all the energy the tank allowed).
    After a (re)start the previous command is q_v = clip(measured q) at zero velocity.

    Args:
        robot: The :class:`~ifc_spg.model.RobotModel`.
        dt: SPG period dT in [s].
    """

    def __init__(self, robot, dt):
        self.robot = robot
        self.dt = float(dt)
        self.prev = None            # (tick, q_v, qdot_v) of the last checked command
        self.commands = 0
        self.violations = 0
        self.accel_overrides = {'position': 0, 'pspm': 0}
        self.examples = []

    def _fail(self, cmd, text):
        self.fail(cmd.tick, text)

    def fail(self, tick, text):
        """Count a violation at ``tick`` (described in :attr:`examples`, the first ten)."""
        self.violations += 1
        if len(self.examples) < 10:
            self.examples.append(f'tick {tick}: {text}')

    def check(self, cmd, q=None, tank_energy=None):
        """Check one command; return the list of violations (empty: fine).

        Args:
            cmd: :class:`~ifc_spg.node.core.Command` (or anything with ``tick``,
                ``position``, ``velocity``, ``resumed``).
            q: The measured joint positions the command answers [rad] (needed after a
                restart, where the previous q_v is the clipped measurement).
            tank_energy: PSPM tank energies after the tick [J] (None without PSPM).
        """
        before = self.violations
        r = self.robot
        pos = np.asarray(cmd.position, dtype=float)
        vel = np.asarray(cmd.velocity, dtype=float)
        if self.prev is not None and cmd.tick == self.prev[0]:
            return []  # a repeated answer (duplicate stamp), checked already
        self.commands += 1
        if pos.shape != (r.n,) or vel.shape != (r.n,):
            self._fail(cmd, f'shapes {pos.shape} {vel.shape}')
            return self.examples[before:]
        if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(vel))):
            self._fail(cmd, 'non-finite command')
            self.prev = None
            return ['non-finite command']
        self._check_box(cmd, pos, vel)
        prev_pos, prev_vel = self._previous(cmd, q)
        if prev_pos is not None:
            self._check_step(cmd, pos, vel, prev_pos, prev_vel, tank_energy)
        self.prev = (cmd.tick, pos.copy(), vel.copy())
        return self.examples[before:] if self.violations > before else []

    def _check_box(self, cmd, pos, vel):
        """q_min <= q_v <= q_max and |qdot_v| <= v_max."""
        r = self.robot
        if np.any(pos < r.q_min) or np.any(pos > r.q_max):
            j = int(np.argmax(np.maximum(r.q_min - pos, pos - r.q_max)))
            self._fail(cmd, f'q_v[{j}] = {pos[j]:.6f} outside [{r.q_min[j]:.6f}, '
                       f'{r.q_max[j]:.6f}]')
        over = np.abs(vel) - r.v_max * (1 + VEL_TOL) - VEL_TOL
        if np.any(over > 0):
            j = int(np.argmax(over))
            self._fail(cmd, f'|qdot_v[{j}]| = {abs(vel[j]):.6f} > v_max {r.v_max[j]:.6f}')

    def _previous(self, cmd, q):
        """The previous command's (q_v, qdot_v); after a (re)start clip(q) at rest."""
        r = self.robot
        if not (cmd.resumed or self.prev is None):
            return self.prev[1], self.prev[2]
        if q is None:
            return None, None
        return np.clip(np.asarray(q, dtype=float), r.q_min, r.q_max), np.zeros(r.n)

    def _check_step(self, cmd, pos, vel, prev_pos, prev_vel, tank_energy):
        """q_v - q_v_prev = dT qdot_v; |qdot_v - qdot_v_prev| <= a_max dT but where forced."""
        r, dt = self.robot, self.dt
        step = pos - prev_pos
        if np.any(np.abs(step - dt * vel) > POS_TOL):
            j = int(np.argmax(np.abs(step - dt * vel)))
            self._fail(cmd, f'q_v[{j}] moved {step[j]:.3e} rad, not dT qdot_v = '
                       f'{dt * vel[j]:.3e}')
        dv = vel - prev_vel
        bad = np.flatnonzero(np.abs(dv) > r.a_max * dt + ACC_TOL)
        if not bad.size:
            return
        box = joint_velocity_bounds(prev_pos, r.q_min, r.q_max, r.v_max, r.a_max, dt)
        for j in bad:
            acc = r.a_max[j] * dt
            forced_down = prev_vel[j] - acc > box.upper[j] and \
                abs(vel[j] - box.upper[j]) <= ACC_TOL
            forced_up = prev_vel[j] + acc < box.lower[j] and \
                abs(vel[j] - box.lower[j]) <= ACC_TOL
            if forced_down or forced_up:
                self.accel_overrides['position'] += 1
            elif tank_energy is not None and tank_energy[j] <= TANK_EMPTY:
                self.accel_overrides['pspm'] += 1
            else:
                self._fail(cmd, f'|qdot_v[{j}] - prev| = {abs(dv[j]):.6f} > a_max dT '
                           f'{acc:.6f} (qdot_v {vel[j]:.6f}, prev {prev_vel[j]:.6f}, '
                           f'tank {None if tank_energy is None else tank_energy[j]})')

    def restart(self):
        """Forget the previous command (the next one starts a new session)."""
        self.prev = None


STACKS = (
    """version: 1
name: soak_reach
tasks:
  - name: posture
    type: joint_position
    equal: [0.6, 0.9, -0.4, -1.2, 0.5, 1.0, -0.6]
    gain: 5.0
""",
    """version: 1
name: soak_circle
tasks:
  - name: circle
    type: cartesian_pose
    frame: tool
    subspace: [x, y, z]
    equal: {trajectory: circle, plane: xy, radius: 0.08, frequency: 0.3, start: init}
    gain: 5.0
  - name: orientation
    type: cartesian_pose
    frame: tool
    subspace: [rx, ry, rz]
    equal: init
    gain: 5.0
  - name: posture
    type: joint_position
    equal: 0.0
    gain: 1.0
""",
    """version: 1
name: soak_sine
tasks:
  - name: wave
    type: joint_position
    equal: {trajectory: sine, amplitude: 0.4, frequency: 0.5, center: init}
    gain: 10.0
""",
    """version: 1
name: soak_hold_limits
tasks:
  - name: force_limits
    type: wrench
    frame: tool
    subspace: [fx, fy, fz]
    lower: -10.0
    upper: 10.0
    gain: 5.0
  - name: position
    type: cartesian_pose
    frame: tool
    subspace: [x, y, z]
    equal: init
    gain: 5.0
  - name: min_torque
    type: joint_torque
    equal: 0.0
    gain: 1.0
""",
    """version: 1
name: soak_contradiction
tasks:
  - name: up
    type: joint_position
    equal: [2.9, 2.0, 2.9, 2.0, 2.9, 2.0, 3.0]
    gain: 50.0
  - name: down
    type: joint_position
    equal: [-2.9, -2.0, -2.9, -2.0, -2.9, -2.0, -3.0]
    gain: 50.0
""",
)


def rss_mb():
    """Resident set size of this process in [MB] (Linux /proc; else the peak RSS)."""
    try:
        with open('/proc/self/statm') as f:
            pages = int(f.read().split()[1])
        return pages * os.sysconf('SC_PAGE_SIZE') / 1e6
    except (OSError, ValueError):  # pragma: no cover - non-Linux
        import resource  # Unix only, and only without /proc

        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3


def run_soak(seconds, robot='lbr_iiwa14', period=10.0, progress=None, stacks=STACKS):
    """Run the soak for ``seconds`` of simulated time; return the report dict.

    Args:
        seconds: Simulated duration in [s].
        robot: Robot configuration name.
        period: Task-stack change period in [s] of simulated time.
        progress: Print a progress line to this stream every 10 % (None: quiet).
        stacks: Task-stack texts, sent in turn.
    """
    soak = _Soak(robot, seconds, period, stacks)
    try:
        for k in range(soak.n_ticks):
            soak.tick(k)
            soak.sample(k, progress)
        return soak.report(time.perf_counter() - soak.wall0)
    finally:
        soak.sim.close()


class _Soak:
    """The simulation, the SPG, the checker and what the report counts."""

    def __init__(self, robot, seconds, period, stacks):
        from sim_bridge.simulation import SimConfig, Simulation  # MuJoCo: only when soaking

        self.robot, self.stacks = robot, stacks
        self.sim = Simulation(SimConfig(robot=robot, scene='free'))
        self.config = SpgConfig(robot=robot, watchdog_timeout=0.0)
        self.runner = SpgRunner(self.config, robot=self.sim.robot)
        self.checker = CommandChecker(self.sim.robot, self.config.dt)
        self.names = list(self.sim.joint_names)
        self.steps = round(self.config.dt / self.sim.dt)
        self.n_ticks = int(round(seconds / self.config.dt))
        self.per_stack = max(1, int(round(period / self.config.dt)))
        self.per_push = int(round(7.0 / self.config.dt))
        # written up front: the pages are resident before the memory baseline is taken
        self.tick_times = np.full(self.n_ticks, np.nan)
        self.rss_trend = []
        self.exceptions, self.examples = 0, []
        self.stack_events = {'accepted': 0, 'rejected': 0}
        self.statuses = {}
        self.rss_early = None
        self.rss_start = rss_mb()
        self.wall0 = time.perf_counter()
        self.rng = np.random.default_rng(0)

    def tick(self, k):
        """Tick ``k``: the stack and push due, the SPG's answer checked, the physics step."""
        sim, runner = self.sim, self.runner
        try:
            if k % self.per_stack == 0:
                event = runner.handle_task_stack(
                    self.stacks[(k // self.per_stack) % len(self.stacks)])
                self.stack_events['accepted' if event.accepted else 'rejected'] += 1
            if self.per_push and k % self.per_push == self.per_push // 2:
                sim.apply_wrench(sim.contact_chain, self.rng.normal(0.0, 15.0, 6) *
                                 [1, 1, 1, 0.1, 0.1, 0.1], 0.2)
            s = sim.read_state()
            t0 = time.perf_counter()
            cmd = runner.handle_joint_state(self.names, s.q, s.qd, round(s.t * 1e9))
            self.tick_times[k] = time.perf_counter() - t0
            info = runner.spg.info
            self.statuses[info.status] = self.statuses.get(info.status, 0) + 1
            if cmd is None:
                self.checker.fail(k, 'no command for a valid state')
            else:
                self.checker.check(cmd, s.q, info.tank_energy)
                sim.write_command(cmd.position, cmd.velocity)
            sim.step(self.steps)
        except Exception:  # count and go on: the soak reports, it does not stop
            self.exceptions += 1
            if len(self.examples) < 5:
                self.examples.append(traceback.format_exc())
            sim.step(self.steps)

    def sample(self, k, progress):
        """Memory at 10 % and every 10 % of the run (with a progress line)."""
        n = self.n_ticks
        if k == n // 10:
            self.rss_early = rss_mb()
        if n < 10 or (k + 1) % (n // 10) != 0:
            return
        self.rss_trend.append(round(rss_mb(), 1))
        if progress is not None:
            print(f'soak: {100 * (k + 1) // n:3d} % ({(k + 1) * self.config.dt:.0f} s sim, '
                  f'{time.perf_counter() - self.wall0:.0f} s wall), violations '
                  f'{self.checker.violations}, exceptions {self.exceptions}, RSS '
                  f'{self.rss_trend[-1]:.1f} MB', file=progress, flush=True)

    def report(self, wall):
        """The report dict (see the module docstring)."""
        rss_end = rss_mb()
        tenth = max(1, self.n_ticks // 10)
        first, last = self.tick_times[:tenth], self.tick_times[-tenth:]
        checker, early = self.checker, self.rss_early
        return {
            'robot': self.robot, 'ticks': self.n_ticks,
            'sim_seconds': self.n_ticks * self.config.dt,
            'wall_seconds': round(wall, 1), 'stack_changes': self.stack_events,
            'exceptions': self.exceptions, 'exception_examples': self.examples,
            'limit_violations': checker.violations, 'violation_examples': checker.examples,
            'accel_overrides': checker.accel_overrides, 'spg_status_counts': self.statuses,
            'rejected': dict(self.runner.rejected),
            'rss_mb': {'start': round(self.rss_start, 1),
                       'at_10_percent': None if early is None else round(early, 1),
                       'end': round(rss_end, 1), 'every_10_percent': self.rss_trend},
            'rss_growth_mb': round(rss_end - (early if early is not None else self.rss_start),
                                   2),
            'tick_ms': {'first_10_percent': {'p50': _pct(first, 50), 'p99': _pct(first, 99)},
                        'last_10_percent': {'p50': _pct(last, 50), 'p99': _pct(last, 99)}},
            'missed_commands': self.sim.read_state().missed_commands,
        }


def _pct(x, p):
    return float(np.percentile(x, p) * 1e3) if len(x) else math.nan


def main(argv=None):
    """Command line entry (``python -m benchmarks.soak``); returns the exit code."""
    p = argparse.ArgumentParser(prog='python -m benchmarks.soak', description=__doc__.split(
        '\n\n')[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--hours', type=float, default=1.0, help='simulated hours (default 1)')
    p.add_argument('--minutes', type=float, default=None, help='simulated minutes (overrides '
                   '--hours)')
    p.add_argument('--quick', action='store_true', help='60 s of simulated time')
    p.add_argument('--robot', default='lbr_iiwa14', help='robot configuration')
    p.add_argument('--period', type=float, default=10.0, help='stack change period [s]')
    p.add_argument('--json', default=None, help='also write the report to this file')
    args = p.parse_args(argv)
    seconds = 60.0 if args.quick else (args.minutes * 60.0 if args.minutes is not None
                                       else args.hours * 3600.0)
    if not (math.isfinite(seconds) and seconds > 0):
        p.error(f'the duration must be > 0 s, got {seconds!r}')
    report = run_soak(seconds, robot=args.robot, period=args.period, progress=sys.stderr)
    text = json.dumps(report, indent=2)
    print(text)
    if args.json:
        with open(args.json, 'w', encoding='utf-8') as f:
            f.write(text + '\n')
    bad = report['exceptions'] or report['limit_violations'] or report['rss_growth_mb'] >= 20
    return 1 if bad else 0


if __name__ == '__main__':
    sys.exit(main())
