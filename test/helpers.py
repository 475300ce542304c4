"""Helpers shared by the tests: paths, the reach stack, a hand-driven clock, a loopback domain.

Tests import them by name (conftest.py puts this folder on sys.path)::

    from helpers import CONFIG, TARGET, reach_stack
"""

import json
from pathlib import Path
import sys

from ros_testing import LOOPBACK_KEYS, loopback_env

from ifc_spg.ros import msg as ros_msg
from ifc_spg.task_stack import TaskStack

ROOT = Path(__file__).resolve().parent.parent
CONFIG = ROOT / 'config'
BIN = Path(sys.executable).parent          # the console scripts of this environment
DT_NS = 2_000_000                          # [ns] the 500 Hz command period
TARGET = [0.3, 0.7, 0.2, -0.9, 0.1, 1.2, 0.3]  # [rad] the reach stack's iiwa posture


def reach_stack(robot=None, name='reach'):
    """The one-task stack driving the joints to TARGET (gain 5.0), as YAML text.

    Args:
        robot: the ``robot:`` line's value; None leaves the line out.
        name: the stack's name.
    """
    robot_line = '' if robot is None else f'robot: {robot}\n'
    return (f'version: 1\nname: {name}\n{robot_line}tasks:\n  - name: posture\n'
            f'    type: joint_position\n    equal: {TARGET}\n    gain: 5.0\n')


def parse_stack(text):
    """A TaskStack from YAML or JSON text."""
    return TaskStack.from_text(text)


class FakeClock:
    """A monotonic clock [s] the test advances by hand (set ``t``)."""

    def __init__(self, t=0.0):
        self.t = t

    def __call__(self):
        return self.t


def record_spg_topics(node, depth=10000):
    """Subscribe ``node`` to joint_states, command/joint_position and spg/status.

    The history is deep: a lockstep loop runs faster than real time, and a test's Python
    executor (rclpy's in particular) may fall behind it for a while without losing messages.

    Returns:
        The lists (states, commands, status) the messages are appended to; status documents
        parsed from JSON.
    """
    states, commands, status = [], [], []
    node.create_subscription(ros_msg.JointState, 'joint_states', states.append, depth)
    node.create_subscription(ros_msg.JointState, 'command/joint_position', commands.append,
                             depth)
    node.create_subscription(ros_msg.String, 'spg/status',
                             lambda m: status.append(json.loads(m.data)), depth)
    return states, commands, status


def use_loopback(monkeypatch, env=None):
    """Apply the loopback DDS variables of ``env`` (default: a new :func:`loopback_env`, on a
    random domain) to this process for one test; return ``env`` for child processes."""
    env = loopback_env() if env is None else env
    for key in LOOPBACK_KEYS:
        monkeypatch.setenv(key, env[key])
    return env


def once_per_session(tmp_path_factory, name, produce):
    """``produce()``'s JSON-serialisable result, computed once per test session.

    For an expensive module fixture: pytest-xdist may split a module's tests between its
    worker processes, each of which would set the fixture up again. Here the first worker
    that asks runs ``produce`` under a file lock in the session's shared temporary folder
    and writes the result there; the others wait for the lock and read it. Without xdist
    it is ``produce()``. If ``produce`` fails, every worker that asks fails the same way.
    """
    import fcntl
    import os

    root = tmp_path_factory.getbasetemp()
    if os.environ.get('PYTEST_XDIST_WORKER'):
        root = root.parent  # shared by the workers of this session
    path = root / f'{name}.json'
    with open(root / f'{name}.lock', 'w') as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if path.exists():
            return json.loads(path.read_text())
        path.write_text(json.dumps(produce()))
        return json.loads(path.read_text())  # the same (JSON) types in every worker


def replay_cli(argv, result, monkeypatch):
    """``ifc-spg replay ARGV``'s exit code, the CLI deciding and printing on ``result``: the
    replay (a re-run of every tick) the test already ran of the same bag, ``ARGV[0]``. The
    CLI must hand that bag and no robot to the replay (checked here)."""
    from ifc_spg.cli import replay as cli

    def same(bag, robot=None):
        assert (str(bag), robot) == (str(argv[0]), None), (bag, robot, argv)
        return result
    monkeypatch.setattr(cli, 'replay', same)
    return cli.main(argv)


def wait_for(condition, timeout):
    """Poll ``condition()`` every 50 ms for up to ``timeout`` [s]; its last value."""
    import time

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.05)
    return bool(condition())


def start_recorder(procs, path, *topics, name='recorder', instrument=False):
    """Start ``ifc-spg bag record -o path topics...`` in ProcessGroup ``procs`` and wait until
    it records (it prints 'recording'); fails the test with its log otherwise.

    ``instrument=True``, for tests that only read what the nodes under test published: the
    recorder of the built-in backend (on the same domain, whichever backend the nodes run)
    with ``--no-tf``. Its readers are reliable and keep all samples, which it takes in batches
    as raw CDR; the rclpy recorder runs one executor callback per message (60 s of lockstep
    states and wrenches: 52-62 CPU-s against 7, more than spg_node itself).
    """
    env, extra = None, ()
    if instrument:
        env, extra = {**procs.env, 'IFC_SPG_ROS_BACKEND': 'cyclonedds'}, ('--no-tf',)
    rec = procs.start(name, 'bag', 'record', '-o', str(path), *topics, *extra, exe='ifc-spg',
                      env=env)
    assert wait_for(lambda: 'recording' in procs.log(name) or rec.poll() is not None, 60) \
        and rec.poll() is None, procs.log(name)
    return rec


def finish_run(procs, bridge, timeout):
    """The end of a process-level run: ``bridge`` (of ProcessGroup ``procs``, named
    'sim_bridge') ends by itself with exit 0 within ``timeout`` [s]; after 1 s for the last
    command to reach the recorder, 'recorder' stops on SIGINT and 'spg_node' on SIGTERM, both
    with exit 0."""
    import signal

    assert wait_for(lambda: bridge.poll() is not None, timeout), procs.log('sim_bridge')
    assert bridge.returncode == 0, procs.log('sim_bridge')
    wait_for(lambda: False, 1.0)
    assert procs.stop('recorder', signal.SIGINT) == 0, procs.log('recorder')
    assert procs.stop('spg_node') == 0, procs.log('spg_node')


def start_cli(args, env):
    """``python -m ifc_spg.cli ARGS`` with ``env``, its output piped as text."""
    import subprocess

    return subprocess.Popen([sys.executable, '-m', 'ifc_spg.cli', *args], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_cli_line(proc, word, timeout=20.0):
    """The first stdout line of ``proc`` containing ``word``; fails the test after ``timeout``
    [s] or when ``proc`` ends without one."""
    import time

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if word in line:
            return line
        if not line and proc.poll() is not None:
            break
    raise AssertionError(f'no "{word}" from {proc.args}: {proc.stderr.read()}')


def self_collision_run(robot, stack_path, frames, ticks, dt, avoid=True, **spg_kwargs):
    """A shipped self-collision stack in a kinematic closed loop (q = q_v).

    ``avoid=False`` drops its collision_avoidance level. The distances are coal's over all
    of the robot's self pairs, independently of the SPG's cull.

    Returns:
        (closest self distance over the run [m], every q_v inside the joint limits,
        positions of ``frames`` at the end, the SPG).
    """
    import numpy as np
    import pinocchio as pin
    import yaml

    from ifc_spg import SetPointGenerator, TaskStack
    from ifc_spg.geometry import CollisionGeometry, PairQuery

    doc = yaml.safe_load(Path(stack_path).read_text())
    if not avoid:
        doc['tasks'] = [t for t in doc['tasks'] if t['type'] != 'collision_avoidance']
    spg = SetPointGenerator(robot, TaskStack.from_dict(doc), dt=dt, **spg_kwargs)
    geometry = CollisionGeometry(robot)
    query = PairQuery(geometry, geometry.self_pairs())
    data = robot.create_data()
    q, qdot = robot.q_home.copy(), np.zeros(robot.n)
    worst, inside = np.inf, True
    for k in range(ticks):
        q = spg.step(q, qdot, k * dt)
        qdot = spg.qdot_v.copy()
        inside &= bool(np.all(q >= robot.q_min) and np.all(q <= robot.q_max))
        pin.forwardKinematics(robot.model, data, q)
        worst = min(worst, query.distances_only(data).min())
    pin.framesForwardKinematics(robot.model, data, q)
    return worst, inside, [data.oMf[robot.frame_id(f)].translation.copy() for f in frames], spg
