"""Nodes always find each other on one machine: start/stop cycles of a node set on one domain.

Each cycle starts ``spg_node``, ``task_publisher`` and a robot — ``sim_bridge`` (realtime) or an
external rclpy driver (``external_robot.py``, joint states at 100 Hz, as a ros2_control robot)
in turn — at the same moment, next to four idle participants and this test's listener that
stay alive all along (8 participants on the domain), and stops them again (every third robot
is killed with SIGKILL, leaving what a crash leaves behind). Every cycle must reach its first
command within 1.5 s of the last start-up line of its nodes.

30 cycles on rclpy (Fast DDS with ``config/fastdds_loopback.xml``, which
``ros_testing.loopback_env`` sets), 10 on the built-in backend.
"""

import os
import signal
import sys
import time

from helpers import CONFIG, ROOT, reach_stack, use_loopback, wait_for
import pytest
from ros_testing import ProcessGroup

from ifc_spg import ros
from ifc_spg.ros import msg as ros_msg

pytestmark = [pytest.mark.dds, pytest.mark.ros, pytest.mark.slow, pytest.mark.realtime]

# 30 on rclpy (Fast DDS, whose discovery this is about); 10 on the built-in backend, whose
# second pass re-runs every ROS-level test (the suite's time)
CYCLES = int(os.environ.get('IFC_SPG_DISCOVERY_CYCLES', '30' if ros.BACKEND == 'rclpy' else '10'))
FIRST_COMMAND_S = 1.5   # [s] after the last start-up line (worst seen 0.38 s, load 8 on 2 cores)
IDLE = ('from ifc_spg import ros; ros.init(); node = ros.Node("idle"); print("idle", flush=True);'
        ' ros.spin(node)')
STARTED = {'spg_node': 'waiting for joint_states', 'sim_bridge': 'sim_bridge: robot',
           'external_robot': 'external_robot: publishing', 'task_publisher': 'task_publisher:'}


def _started_at(procs, names, timeout):
    """The time [monotonic s] at which the last of ``names`` printed its start-up line."""
    seen = {}
    deadline = time.monotonic() + timeout
    while len(seen) < len(names) and time.monotonic() < deadline:
        for name in names:
            if name not in seen and STARTED[name] in procs.log(name):
                seen[name] = time.monotonic()
            assert procs.procs[name].poll() is None, procs.log(name)
        time.sleep(0.01)
    assert len(seen) == len(names), {n: procs.log(n) for n in names if n not in seen}
    return max(seen.values())


def test_node_sets_find_each_other_in_every_cycle(tmp_path, monkeypatch):
    env = use_loopback(monkeypatch)
    stack = tmp_path / 'reach.yaml'
    stack.write_text(reach_stack('lbr_iiwa14'))
    idle = ProcessGroup(tmp_path / 'idle', env)
    (tmp_path / 'idle').mkdir()
    ros.init(['test'])
    node = ros.Node('listener')
    commands = []
    node.create_subscription(ros_msg.JointState, 'command/joint_position',
                             lambda m: commands.append(time.monotonic()), 100)
    delays = []
    try:
        for i in range(4):
            idle.start(f'idle{i}', '-c', IDLE, exe='python')
        assert wait_for(lambda: all('idle' in idle.log(f'idle{i}') for i in range(4)), 60)
        for cycle in range(CYCLES):
            log_dir = tmp_path / f'cycle{cycle:02d}'
            log_dir.mkdir()
            procs = ProcessGroup(log_dir, env)
            robot = 'sim_bridge' if cycle % 2 == 0 else 'external_robot'
            try:
                procs.start('spg_node', '--ros-args', '--params-file',
                            str(CONFIG / 'lbr_iiwa14.yaml'))
                if robot == 'sim_bridge':
                    procs.start('sim_bridge', '--ros-args', '-p', 'robot:=lbr_iiwa14', '-p',
                                'scene:=free', '-p', 'mode:=realtime', '-p', 'state_rate:=100.0')
                else:
                    procs.start('external_robot', str(ROOT / 'test' / 'external_robot.py'),
                                exe='python')
                procs.start('task_publisher', str(stack))
                commands.clear()
                last_line = _started_at(procs, ['spg_node', robot, 'task_publisher'], 90)
                ros.spin_until(lambda: bool(commands), 30.0, nodes=node)
                assert commands, (f'cycle {cycle}: no command 30 s after the start-up',
                                  procs.log('spg_node'), procs.log(robot))
                delays.append(max(0.0, commands[0] - last_line))
                if cycle % 3 == 2:
                    procs.procs[robot].kill()
            finally:
                procs.close(sig=signal.SIGTERM)
        print(f'first command after the last start-up line over {CYCLES} cycles: '
              f'max {max(delays):.3f} s, median {sorted(delays)[len(delays) // 2]:.3f} s',
              file=sys.stderr)
    finally:
        idle.close()
        ros.shutdown()
    slow = [(i, round(d, 3)) for i, d in enumerate(delays) if d > FIRST_COMMAND_S]
    assert not slow, f'cycles whose first command came later than {FIRST_COMMAND_S} s: {slow}'
