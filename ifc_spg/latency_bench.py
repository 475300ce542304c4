"""Tick-to-command latency of a realtime DDS run: ``sim_bridge`` (realtime, 500 Hz, iiwa,
free scene) and ``spg_node`` as separate processes over loopback DDS.

    python -m ifc_spg.latency_bench [--seconds 60] [--json]

This process listens to ``joint_states`` and ``command/joint_position``; the latency of a
tick is the arrival time (here, ``time.monotonic``) of the command answering a state (same
header stamp) minus the arrival time of that state — the bridge's publish, the SPG's tick
and the command's way back, over the same loopback DDS. Reported: p50/p99/max [ms],
missed ticks (states without a command here, and the bridge's own count of command periods
without a command, from its exit line) and the bridge's pacing lateness.
"""

import argparse
import json
import os
from pathlib import Path
import re
import subprocess
import sys
import tempfile
import time

import numpy as np

__all__ = ['main', 'run']

STACK = """version: 1
name: reach
robot: lbr_iiwa14
tasks:
  - name: posture
    type: joint_position
    equal: [0.3, 0.7, 0.2, -0.9, 0.1, 1.2, 0.3]
    gain: 1.0
"""


def _stamp(msg):
    return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec


def run(seconds=60.0, stream=sys.stderr):
    """Run the bridge and the SPG for ``seconds`` [s] of realtime; return the results dict."""
    from ifc_spg.ros import dds, messages
    from ifc_spg.ros.testing import loopback_env, stop_process
    from ifc_spg.runner import find_config_dir

    bindir = Path(sys.executable).parent
    env = loopback_env()
    for key in ('CYCLONEDDS_URI', 'ROS_DOMAIN_ID', 'IFC_SPG_ROS_BACKEND'):
        os.environ[key] = env[key]
    tmp = Path(tempfile.mkdtemp(prefix='latency_bench.'))
    (tmp / 'reach.yaml').write_text(STACK)
    state_at, command_at = {}, {}
    dds.init(['latency_bench'])
    node = dds.Node('latency_bench')
    node.create_subscription(messages.JointState, 'joint_states',
                             lambda m: state_at.setdefault(_stamp(m), time.monotonic()), 100)
    node.create_subscription(messages.JointState, 'command/joint_position',
                             lambda m: command_at.setdefault(_stamp(m), time.monotonic()), 100)
    procs, logs = [], []

    def start(name, *args):
        logs.append(open(tmp / f'{name}.log', 'w+'))
        procs.append(subprocess.Popen([str(bindir / name), *args], env=env, stdout=logs[-1],
                                      stderr=subprocess.STDOUT))
        return procs[-1]

    try:
        spg = start('spg_node', '--ros-args', '--params-file',
                    str(find_config_dir() / 'lbr_iiwa14.yaml'), '-p',
                    f"task_stack_file:={tmp / 'reach.yaml'}")
        time.sleep(2.0)  # let the SPG start (imports) before the clock runs
        bridge = start('sim_bridge', '--ros-args', '-p', 'robot:=lbr_iiwa14', '-p',
                       'scene:=free', '-p', 'mode:=realtime', '-p', f'duration:={seconds}')
        print(f'latency_bench: realtime run of {seconds:g} s (logs in {tmp})', file=stream,
              flush=True)
        while bridge.poll() is None:
            dds.spin_until(lambda: False, 0.2, nodes=node)
        dds.spin_until(lambda: False, 0.5, nodes=node)
        stop_process(spg)
    finally:
        for proc in procs:
            stop_process(proc)
        for f in logs:
            f.close()
        dds.shutdown()
    bridge_log = (tmp / 'sim_bridge.log').read_text()
    pacing = re.search(r'p50 lateness (\d+) us, p99 (\d+) us, (\d+) overrun\(s\), (\d+) missed',
                       bridge_log)
    # a command before its state arrived here (possible: both are separate DDS readers)
    lat = np.array([command_at[s] - state_at[s] for s in state_at if s in command_at])
    out = {
        'seconds': seconds,
        'states': len(state_at),
        'commands': len(command_at),
        'expected_ticks': round(seconds * 500),
        'missed_here': len([s for s in state_at if s not in command_at]),
        'latency_ms': {'p50': float(np.percentile(lat, 50) * 1e3),
                       'p99': float(np.percentile(lat, 99) * 1e3),
                       'max': float(np.max(lat) * 1e3)} if lat.size else None,
        'bridge_missed_commands': int(pacing.group(4)) if pacing else None,
        'bridge_pacing_us': {'p50': int(pacing.group(1)), 'p99': int(pacing.group(2)),
                             'overruns': int(pacing.group(3))} if pacing else None,
        'logs': str(tmp),
    }
    return out


def main(argv=None):
    """``python -m ifc_spg.latency_bench``; exit 1 if nothing was measured."""
    parser = argparse.ArgumentParser(prog='python -m ifc_spg.latency_bench',
                                     description=__doc__.split('\n')[0])
    parser.add_argument('--seconds', type=float, default=60.0, help='realtime run [s]')
    parser.add_argument('--json', action='store_true', help='print the result as JSON')
    opts = parser.parse_args(sys.argv[1:] if argv is None else argv)
    res = run(opts.seconds)
    if opts.json:
        print(json.dumps(res, indent=1))
    else:
        lat = res['latency_ms'] or {'p50': float('nan'), 'p99': float('nan'),
                                    'max': float('nan')}
        print(f"{res['states']} states, {res['commands']} commands in {res['seconds']:g} s "
              f"(expected {res['expected_ticks']}); tick-to-command latency p50 "
              f"{lat['p50']:.3f} ms, p99 {lat['p99']:.3f} ms, max {lat['max']:.3f} ms; missed "
              f"ticks: {res['missed_here']} without a command here, "
              f"{res['bridge_missed_commands']} counted by the bridge; bridge pacing "
              f'{res["bridge_pacing_us"]}')
    return 0 if res['latency_ms'] else 1


if __name__ == '__main__':
    sys.exit(main())
