"""Fuzzing the SPG node's input path (SpgRunner): random and mutated joint-state messages and
task stacks. No exception escapes, every message either ticks or is counted as rejected, and
every command satisfies the limit guarantees (CommandChecker, README.md "What is always true")."""

import math

from helpers import CONFIG, DT_NS, FakeClock
import numpy as np
import pytest

from benchmarks.soak import STACKS, CommandChecker
from ifc_spg.model import RobotModel
from ifc_spg.node.config import SpgConfig
from ifc_spg.node.core import REJECT_REASONS, SpgRunner

TASKS = CONFIG / 'tasks'
SPECIALS = (math.nan, math.inf, -math.inf, 1e308, -1e308, 5e-324, 1e6, -1e6)


class TrackingRobot:
    """A joint-impedance robot in one line: q moves a fraction of the way to q_v each tick."""

    def __init__(self, q):
        self.q = np.array(q, dtype=float)
        self.qd = np.zeros_like(self.q)

    def follow(self, q_v, dt=0.002, rate=0.3):
        new = self.q + rate * (q_v - self.q)
        self.qd = (new - self.q) / dt
        self.q = new


@pytest.fixture(scope='module')
def robot():
    return RobotModel.from_config('lbr_iiwa14')


def _mutate_state(rng, names, robot, q, qd, stamp):
    """One joint-state message (names, position, velocity, stamp) and its mutation kind."""
    names = list(names)
    pos = q + rng.normal(0.0, 0.002, q.size)
    vel = qd.copy()
    kind = int(rng.integers(0, 16))
    if kind == 1:
        pos[rng.integers(q.size)] = SPECIALS[rng.integers(len(SPECIALS))]
    elif kind == 2:
        vel[rng.integers(q.size)] = SPECIALS[rng.integers(len(SPECIALS))]
    elif kind == 3:
        pos = rng.uniform(-4.0, 4.0, q.size)       # anywhere, also beyond the limits
    elif kind == 4:
        pos = np.where(rng.random(q.size) < 0.5, robot.q_max, robot.q_min)  # at the limits
    elif kind == 5:
        stamp = [stamp - 3 * DT_NS, stamp - DT_NS, 0, -7, 2**62, math.nan, math.inf,
                 stamp + 0.5, 'now', None][rng.integers(10)]
    elif kind == 6:
        perm = rng.permutation(q.size)
        names, pos, vel = [names[i] for i in perm], pos[perm], vel[perm]
    elif kind == 7:
        vel = []                                    # no velocities: finite differences
    elif kind == 8:
        cut = int(rng.integers(0, q.size))
        names, pos, vel = names[:cut], pos[:cut], vel[:cut]
    elif kind == 9:
        names[rng.integers(q.size)] = ['A9', '', None, 3, 'a1', names[0]][rng.integers(6)]
    elif kind == 10:
        pos = list(pos) + [0.0]
    elif kind == 11:
        pos = [['x'] * q.size, None, 'text', [[1.0]] * q.size][rng.integers(4)]
    elif kind == 12:
        vel = rng.normal(0.0, 1e3, q.size)          # huge but finite velocities
    return names, pos, vel, stamp, kind


def test_fuzz_joint_states(robot):
    """12 000 mutated joint-state messages with stack changes and the watchdog running."""
    clock = FakeClock()
    runner = SpgRunner(SpgConfig(watchdog_timeout=0.05), robot, clock=clock)
    checker = CommandChecker(robot, 0.002)
    rng = np.random.default_rng(20240610)
    body = TrackingRobot(robot.q_home)
    stamp, messages, ticks_seen, kinds = 0, 0, 0, set()
    for k in range(12_000):
        if k % 500 == 0:
            runner.handle_task_stack(STACKS[int(rng.integers(len(STACKS)))])
        if k % 2000 == 1000:    # the source pauses long enough to trip the watchdog
            clock.t += 0.2
            assert runner.check_watchdog() or runner.state != 'running'
        stamp += DT_NS
        clock.t += 0.002
        names, pos, vel, st, kind = _mutate_state(rng, robot.joint_names, robot, body.q,
                                                  body.qd, stamp)
        before = runner.ticks + sum(runner.rejected.values())
        cmd = runner.handle_joint_state(names, pos, vel, st)   # must never raise
        messages += 1
        kinds.add(kind)
        # each message is either one tick or one counted rejection (a duplicate stamp both
        # is counted and answered with the previous command)
        assert runner.ticks + sum(runner.rejected.values()) == before + 1
        runner.check_watchdog()
        if cmd is None:
            continue
        if cmd.tick > ticks_seen:
            ticks_seen = cmd.tick
            q_meas = np.empty(robot.n)
            q_meas[[robot.joint_names.index(n) for n in names]] = np.asarray(pos, float)
            assert checker.check(cmd, q_meas, runner.spg.info.tank_energy) == []
            body.follow(cmd.position)
            body.q = np.clip(body.q, robot.q_min - 0.1, robot.q_max + 0.1)
    assert messages >= 10_000 and kinds == set(range(16))
    assert checker.violations == 0, checker.examples
    assert runner.ticks == checker.commands and runner.ticks > messages // 3
    assert all(runner.rejected[r] > 0 for r in REJECT_REASONS), runner.rejected
    assert runner.watchdog_trips > 0 and runner.resumes > 0
    assert runner.state == 'running'


def _mutate_text(rng, text):
    """A mutated task-stack text: byte edits, number swaps, truncation, duplication."""
    kind = int(rng.integers(0, 8))
    if kind == 0:       # replace a number by an extreme one
        import re
        nums = list(re.finditer(r'-?\d+(\.\d+)?', text))
        if nums:
            m = nums[rng.integers(len(nums))]
            new = ['1e12', '-1e12', '0', '1e-300', '.nan', '.inf', '99999999999999999999',
                   '-0.0', '1e308'][rng.integers(9)]
            text = text[:m.start()] + new + text[m.end():]
    elif kind == 1:     # flip characters
        chars = list(text)
        for _ in range(int(rng.integers(1, 6))):
            i = int(rng.integers(len(chars)))
            chars[i] = chr(int(rng.integers(9, 127)))
        text = ''.join(chars)
    elif kind == 2:     # truncate
        text = text[:int(rng.integers(len(text)))]
    elif kind == 3:     # delete a line
        lines = text.splitlines(True)
        del lines[int(rng.integers(len(lines)))]
        text = ''.join(lines)
    elif kind == 4:     # duplicate a line
        lines = text.splitlines(True)
        i = int(rng.integers(len(lines)))
        lines.insert(i, lines[i])
        text = ''.join(lines)
    elif kind == 5:     # oversize
        text = text + '#' + 'x' * 300_000
    elif kind == 6:     # swap the gain for a huge one or a name for another type
        text = text.replace('gain: 5.0', 'gain: 1.0e9').replace('joint_position', 'wrench')
    elif kind == 7:     # not text at all
        text = [None, b'\xff\xfe', 12, {'version': 1}, '', '{}', '[', '*a'][rng.integers(8)]
    return text


@pytest.mark.slow
def test_fuzz_task_stacks(robot):
    """10 000 mutated task stacks; each accepted one runs 3 ticks, every command checked."""
    sources = list(STACKS) + [p.read_text() for p in sorted(TASKS.glob('*.yaml'))]
    # the iiwa's shipped ceiling (config/lbr_iiwa14.yaml): the shipped stacks that ask for a
    # power budget are accepted and run, not only parsed
    runner = SpgRunner(SpgConfig(watchdog_timeout=0.0, pspm_max_power=2.0), robot)
    checker = CommandChecker(robot, 0.002)
    rng = np.random.default_rng(7)
    body = TrackingRobot(robot.q_home)
    stamp = 0
    accepted = rejected = 0
    for _ in range(10_000):
        text = _mutate_text(rng, sources[int(rng.integers(len(sources)))])
        event = runner.handle_task_stack(text)      # must never raise
        assert isinstance(event.message, str) and event.message
        if not event.accepted:
            rejected += 1
            assert event.message.startswith('task stack rejected')
            assert runner.errors[-1]['source'] == 'task_stack'
            continue
        accepted += 1
        for _ in range(3):
            stamp += DT_NS
            cmd = runner.handle_joint_state(robot.joint_names, body.q, body.qd, stamp)
            assert cmd is not None
            assert checker.check(cmd, body.q, runner.spg.info.tank_energy) == []
            body.follow(cmd.position)
    assert checker.violations == 0, checker.examples
    assert accepted > 1000 and rejected > 1000, (accepted, rejected)
    assert runner.ticks == 3 * accepted and sum(runner.rejected.values()) == 0


def test_the_checker_catches_violations(robot):
    """CommandChecker is the oracle of these tests: it must flag each kind of violation."""
    from ifc_spg.node.core import Command

    names = robot.joint_names
    q = robot.q_home.copy()
    z = np.zeros(robot.n)

    def first():
        c = CommandChecker(robot, 0.002)
        assert c.check(Command(0, names, q, z, 1, True), q) == []
        return c

    v = np.zeros(robot.n)
    v[0] = 0.01
    assert first().check(Command(0, names, q + 0.002 * v, v, 2, False), q) == []
    bad = {
        'non-finite': (np.where(np.arange(robot.n) == 2, np.nan, q), z),
        'outside': (np.where(np.arange(robot.n) == 1, robot.q_max[1] + 1e-9, q), z),
        'v_max': (q + 0.002 * robot.v_max * 1.01, robot.v_max * 1.01),
        'not dT qdot_v': (q + 1e-6, z),
        'a_max': (q + 0.002 * 0.1, np.full(robot.n, 0.1)),   # 0.1 rad/s in one tick
    }
    for what, (pos, vel) in bad.items():
        c = first()
        assert c.check(Command(0, names, pos, vel, 2, False), q, np.ones(robot.n)), what
        assert c.violations >= 1
    # the documented exception: an empty PSPM tank allows the harder step
    c = first()
    e = np.ones(robot.n)
    e[:] = 0.0
    assert c.check(Command(0, names, q + 0.002 * 0.1, np.full(robot.n, 0.1), 2, False), q,
                   e) == []
    assert c.accel_overrides['pspm'] == robot.n
