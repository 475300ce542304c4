"""Fault injection in-process: the SPG node's logic (SpgRunner) and the MuJoCo bridge
(Simulation) in lockstep, with adversarial stacks, solver failures, lost/late/duplicated
joint states, a silent source (watchdog), a restarted bridge and a restarted SPG. Each test
asserts the guarantee of README.md "What is always true", every command through CommandChecker."""

from helpers import TARGET, FakeClock, reach_stack
import numpy as np
import pytest

from benchmarks.soak import STACKS, CommandChecker
from ifc_spg.cascade.daqp import CascadeResult
from ifc_spg.node.config import SpgConfig
from ifc_spg.node.core import SpgRunner
from sim_bridge.simulation import SimConfig, Simulation

DT = 0.002
REACH = reach_stack()


class Loop:
    """The lockstep loop of the bridge and the SPG, with hooks to inject faults.

    Each :meth:`tick` reads the simulated state, hands it to the runner (unless dropped),
    checks and applies the command and steps the physics one command period.
    """

    def __init__(self, q0=None, scene='free', watchdog=0.05, robot='lbr_iiwa14'):
        self.sim = Simulation(SimConfig(robot=robot, scene=scene, q0=q0))
        self.robot = self.sim.robot
        self.clock = FakeClock(1000.0)
        self.runner = SpgRunner(SpgConfig(robot=robot, watchdog_timeout=watchdog),
                                robot=self.robot, clock=self.clock)
        self.checker = CommandChecker(self.robot, DT)
        self.names = list(self.sim.joint_names)
        self.commands = []
        self.statuses = []

    def state(self):
        s = self.sim.read_state()
        return s, round(s.t * 1e9)

    def deliver(self, s, stamp):
        """Hand one state to the runner; check and return the command (or None)."""
        cmd = self.runner.handle_joint_state(self.names, s.q, s.qd, stamp)
        self.statuses.append(self.runner.spg.info.status)
        if cmd is not None:
            problems = self.checker.check(cmd, s.q, self.runner.spg.info.tank_energy)
            assert problems == [], problems
            self.commands.append(cmd)
        return cmd

    def tick(self, deliver=True):
        s, stamp = self.state()
        cmd = self.deliver(s, stamp) if deliver else None
        if cmd is not None:
            self.sim.write_command(cmd.position, cmd.velocity)
        self.sim.step(2)
        self.clock.t += DT
        self.runner.check_watchdog()
        return cmd

    def run(self, seconds, **kw):
        return [self.tick(**kw) for _ in range(round(seconds / DT))]


def _singular_unreachable():
    return """version: 1
name: unreachable
tasks:
  - name: far
    type: cartesian_pose
    frame: tool
    subspace: [x, y, z]
    equal: [2.5, 0.0, 0.2]
    gain: 50.0
  - name: posture
    type: joint_position
    equal: 0.0
    gain: 1.0
"""


ADVERSARIAL = {
    # stretched arm (a singular configuration), Cartesian target 2.5 m away
    'singular_unreachable': (np.zeros(7), _singular_unreachable()),
    # every joint 1 mrad inside its limit, a posture at the limits with a huge gain
    'at_limits_huge_gain': ('max', """version: 1
name: beyond
tasks:
  - name: beyond
    type: joint_position
    equal: [2.967, 2.094, 2.967, 2.094, 2.967, 2.094, 3.054]
    gain: 1.0e6
"""),
    # two equal-priority-looking contradictory targets at the limits, gain 50
    'contradictory': (None, STACKS[4]),
    # a 100 kN force with nothing to push against, and a fast huge circle
    'huge_force_fast_circle': (None, """version: 1
name: wild
tasks:
  - name: force
    type: wrench
    frame: tool
    subspace: [fx, fy, fz]
    equal: [0.0, 0.0, -1.0e5]
    gain: 1.0e3
  - name: circle
    type: cartesian_pose
    frame: tool
    subspace: [x, y]
    equal: {trajectory: circle, plane: xy, radius: 1.0, frequency: 20.0, start: init}
    gain: 1.0e4
"""),
}


@pytest.mark.parametrize('case', sorted(ADVERSARIAL))
def test_adversarial_stacks_keep_every_command_inside_the_limits(case):
    q0, stack = ADVERSARIAL[case]
    if isinstance(q0, str):
        from ifc_spg.model import RobotModel
        r = RobotModel.from_config('lbr_iiwa14')
        q0 = r.q_max - 1e-3
    loop = Loop(q0=None if q0 is None else tuple(q0))
    assert loop.runner.handle_task_stack(stack).accepted
    loop.run(1.0)
    r = loop.robot
    assert len(loop.commands) == 500 and loop.checker.violations == 0
    q_v = np.array([c.position for c in loop.commands])
    # the guarantee is exercised, not vacuous: something pushed q_v or qdot_v to a limit
    near_limit = np.any((q_v <= r.q_min + 1e-3) | (q_v >= r.q_max - 1e-3))
    fast = np.any(np.abs([c.velocity for c in loop.commands]) >= 0.5 * r.v_max)
    assert near_limit or fast or 'fallback' in loop.statuses
    assert not loop.sim.warnings()


def test_solver_failures_brake_hold_and_are_reported(monkeypatch):
    loop = Loop(watchdog=0.0)
    assert loop.runner.handle_task_stack(STACKS[2]).accepted     # a moving sine
    loop.run(0.6)
    moving = np.max(np.abs(loop.commands[-1].velocity))
    assert moving > 0.05
    spg = loop.runner.spg
    n = loop.robot.n
    mode = {'k': 0}

    def broken(levels, box):
        mode['k'] += 1
        if mode['k'] % 2:
            raise RuntimeError('solver exploded')
        return CascadeResult(np.full(n, np.nan), [], 'ok', -1)   # a NaN "solution"

    monkeypatch.setattr(spg.solver, 'solve', broken)              # the public cascade
    brake_ticks = int(np.ceil(moving / (np.min(loop.robot.a_max) * DT))) + 1
    cmds = loop.run(brake_ticks * DT + 0.1)
    assert set(loop.statuses[-len(cmds):]) == {'hold'}
    doc = loop.runner.status()
    assert doc['spg']['status'] == 'hold' and 'holding q_v' in doc['spg']['message']
    assert any(e['source'] == 'spg' for e in doc['errors'])
    assert loop.runner.diagnostics().level == 'ERROR'
    # braked within a_max (checked per command), then held: zero velocity, q_v frozen
    tail = cmds[brake_ticks:]
    assert all(np.all(c.velocity == 0.0) for c in tail)
    assert all(np.array_equal(c.position, tail[0].position) for c in tail)
    monkeypatch.undo()                                            # the solver recovers
    loop.run(0.2)
    assert loop.statuses[-1] == 'ok' and loop.runner.diagnostics().level == 'OK'
    assert loop.checker.violations == 0


def test_a_task_that_raises_holds_instead_of_crashing():
    loop = Loop(watchdog=0.0)
    assert loop.runner.handle_task_stack(REACH).accepted
    loop.run(0.2)
    task = loop.runner.spg.tasks[0]
    task.level = lambda kin, t: (_ for _ in ()).throw(ValueError('bad Jacobian'))
    loop.run(0.3)
    assert loop.statuses[-1] == 'hold'
    assert 'ValueError: bad Jacobian' in loop.runner.status()['spg']['message']
    assert np.all(loop.commands[-1].velocity == 0.0)


def test_joint_states_stop_watchdog_then_resume_from_the_measured_q_without_a_jump():
    loop = Loop(watchdog=0.05)
    assert loop.runner.handle_task_stack(REACH).accepted
    loop.run(1.0)
    sent = len(loop.commands)
    # the states stop (the bridge keeps simulating, holding q_v); a person pushes the arm
    loop.sim.apply_wrench(loop.sim.contact_chain, [0, 40.0, 0, 0, 0, 0], 0.25)
    tripped_at = None
    for k in range(150):
        loop.tick(deliver=False)
        if tripped_at is None and loop.runner.state == 'stale':
            tripped_at = k
    assert tripped_at is not None and 0.05 <= (tripped_at + 1) * DT <= 0.05 + 2 * DT
    assert len(loop.commands) == sent                   # nothing commanded while stale
    assert loop.runner.diagnostics().level == 'STALE'
    s, stamp = loop.state()
    assert np.max(np.abs(s.q - loop.commands[-1].position)) > 0.01   # the arm moved
    cmd = loop.tick()                                                 # states are back
    assert cmd.resumed and loop.runner.resumes == 1 and loop.runner.state == 'running'
    # no jump: the first command is the measured q plus at most one v_max step
    assert np.all(np.abs(cmd.position - s.q) <= loop.robot.v_max * DT + 1e-12)
    loop.run(4.0)
    np.testing.assert_allclose(loop.commands[-1].position, TARGET, atol=5e-3)
    assert loop.checker.violations == 0


def test_bridge_restart_is_rejected_until_the_watchdog_then_restarts_from_the_new_q():
    loop = Loop(watchdog=0.05)
    assert loop.runner.handle_task_stack(REACH).accepted
    loop.run(0.5)
    # the bridge restarts: a new simulation at another pose, its clock from 0 again
    q_new = (0.5, 0.2, -0.3, -1.5, 0.3, 0.8, -0.4)
    loop.sim = Simulation(SimConfig(robot='lbr_iiwa14', scene='free', q0=q_new))
    tries = 0
    while True:   # lockstep: the new bridge re-sends its first state until it is answered
        s, stamp = loop.state()
        cmd = loop.deliver(s, stamp)
        if cmd is not None:
            break
        tries += 1
        loop.clock.t += DT
        loop.runner.check_watchdog()
        assert tries < 100
    assert loop.runner.rejected['stamp_backwards'] == tries
    assert tries == pytest.approx(0.05 / DT, abs=2)     # until the watchdog tripped
    assert cmd.resumed and loop.runner.resumes == 1
    assert np.all(np.abs(cmd.position - np.array(q_new)) <= loop.robot.v_max * DT + 1e-12)
    assert loop.runner.stack_name == 'reach'            # the stack survives the restart
    loop.sim.write_command(cmd.position, cmd.velocity)
    loop.sim.step(2)
    loop.run(4.0)
    np.testing.assert_allclose(loop.commands[-1].position, TARGET, atol=5e-3)


def test_spg_restart_starts_from_the_measured_q_and_the_latched_stack():
    hold = """version: 1
name: hold_here
tasks:
  - name: pose
    type: cartesian_pose
    frame: tool
    subspace: [x, y, z, rx, ry, rz]
    equal: init
    gain: 5.0
"""
    loop = Loop(watchdog=0.05)
    assert loop.runner.handle_task_stack(REACH).accepted
    loop.run(0.5)
    # the SPG process dies; the bridge holds the last q_v while a push moves the arm
    loop.sim.apply_wrench(loop.sim.contact_chain, [30.0, 0, 0, 0, 0, 0], 0.1)
    loop.run(0.2, deliver=False)
    s, stamp = loop.state()
    old_q_v = loop.commands[-1].position
    loop.runner = SpgRunner(SpgConfig(watchdog_timeout=0.05), robot=loop.robot,
                            clock=loop.clock)
    loop.checker.restart()
    assert loop.runner.handle_task_stack(hold).accepted  # latched: delivered on (re)connect
    cmd = loop.tick()
    assert cmd.resumed and cmd.tick == 1
    assert np.all(np.abs(cmd.position - s.q) <= loop.robot.v_max * DT + 1e-12)
    assert np.max(np.abs(old_q_v - s.q)) > 0.005      # it did not resume the old q_v
    loop.run(1.0)
    # 'init' was captured at the measured pose: the arm stays close to where it was found
    assert np.max(np.abs(loop.commands[-1].position - s.q)) < 0.05
    assert loop.checker.violations == 0


def test_dropped_delayed_and_duplicated_states_are_counted_and_the_task_still_converges():
    loop = Loop(watchdog=0.05)
    assert loop.runner.handle_task_stack(REACH).accepted
    rng = np.random.default_rng(3)
    dropped = duplicated = late = silent = 0
    held = None
    for _ in range(round(4.0 / DT)):
        s, stamp = loop.state()
        r = rng.random()
        cmd = None
        if r < 0.15:                        # lost on the way
            dropped += 1
        elif r < 0.25 and held is None:     # delayed: arrives after the next one
            held = (s, stamp)
        else:
            cmd = loop.deliver(s, stamp)
            if r < 0.35:                    # delivered twice
                assert loop.deliver(s, stamp) is cmd
                duplicated += 1
            if held is not None:            # the late one arrives now: too old
                assert loop.deliver(*held) is None
                late += 1
                held = None
        if cmd is not None:
            loop.sim.write_command(cmd.position, cmd.velocity)
        elif loop.commands:
            silent += 1                     # the bridge holds q_v for this period
        loop.sim.step(2)
        loop.clock.t += DT
        loop.runner.check_watchdog()
    rej = loop.runner.rejected
    assert rej['duplicate_stamp'] == duplicated and rej['stamp_backwards'] == late
    assert dropped > 100 and duplicated > 100 and late > 100
    assert loop.runner.watchdog_trips == 0 and loop.checker.violations == 0
    assert loop.sim.read_state().missed_commands == silent >= dropped + late - 3
    np.testing.assert_allclose(loop.sim.read_state().q, TARGET, atol=0.02)


def test_absurd_finite_measurements_and_bad_stamps_never_poison_the_spg():
    """Regression: q = 1e308 overflowed the PSPM tank to NaN (every later command NaN), and a
    NaN or fractional stamp raised out of the runner."""
    from ifc_spg.model import RobotModel

    robot = RobotModel.from_config('lbr_iiwa14')
    runner = SpgRunner(SpgConfig(watchdog_timeout=0.0), robot)
    checker = CommandChecker(robot, DT)
    assert runner.handle_task_stack(REACH).accepted
    names, q, z = robot.joint_names, robot.q_home.copy(), np.zeros(robot.n)
    stamp = 0
    for k in range(40):
        stamp += 2_000_000
        meas = np.full(robot.n, 1e308 if k % 2 else -1e308) if 10 <= k < 14 else q
        cmd = runner.handle_joint_state(names, meas, z, stamp)
        assert checker.check(cmd, meas, runner.spg.info.tank_energy) == []
        assert np.all(np.isfinite(runner.spg.tanks.energy))
    assert checker.violations == 0 and runner.spg.info.status == 'ok'
    for bad in (float('nan'), float('inf'), stamp + 0.5, 'now', None):
        assert runner.handle_joint_state(names, q, z, bad) is None
    assert runner.rejected['non_finite'] == 5
    # positions given as text are rejected, not raised
    assert runner.handle_joint_state(names, ['x'] * robot.n, z, stamp + 2_000_000) is None
    assert runner.rejected['non_finite'] == 6
    # a finite-difference velocity that overflows is rejected
    assert runner.handle_joint_state(names, np.full(robot.n, -1e308), z, stamp + 4_000_000)
    assert runner.handle_joint_state(names, np.full(robot.n, 1e308), [],
                                     stamp + 6_000_000) is None
    assert runner.rejected['non_finite'] == 7
