"""Two processes through their console scripts: 500 Hz JointState over loopback, and the
``cyclonedds`` CLI seeing the ROS type on ``rt/...`` of a running node."""

import json
import subprocess
import time

from helpers import BIN
import pytest
from ros_testing import loopback_env, stop_process

pytestmark = [pytest.mark.dds, pytest.mark.ros]

IFC_SPG = str(BIN / 'ifc-spg')
CYCLONEDDS = str(BIN / 'cyclonedds')
RATE_HZ, DURATION_S = 500.0, 10.0



def _read_line(proc, timeout):
    """Next stdout line of ``proc`` within ``timeout`` [s] (the child flushes each line)."""
    import selectors

    sel = selectors.DefaultSelector()
    sel.register(proc.stdout, selectors.EVENT_READ)
    try:
        if sel.select(timeout):
            return proc.stdout.readline()
    finally:
        sel.close()
    return ''


@pytest.mark.realtime
def test_talker_listener_500hz_for_10s_loses_nothing():
    """Reliable, with a history that holds the run: nothing is lost however far the listener
    falls behind (with the tools' default depth 10, 874 of 5000 went at load 9 on 2 cores:
    keep-last drops the oldest, as it should)."""
    env = loopback_env()
    count = int(RATE_HZ * DURATION_S)
    listener = subprocess.Popen(
        [IFC_SPG, 'ros', 'listener', '--ros-args', '-p', f'count:={count}',
         '-p', f'timeout_s:={DURATION_S + 30}', '-p', f'depth:={count}'],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    talker = None
    try:
        ready = json.loads(_read_line(listener, 30) or '{}')
        assert ready.get('ready'), listener.stderr.read() if listener.poll() is not None else ''
        talker = subprocess.Popen(
            [IFC_SPG, 'ros', 'talker', '--ros-args', '-p', f'rate:={RATE_HZ}',
             '-p', f'count:={count}', '-p', 'wait_for_subscribers:=1', '-p', f'depth:={count}',
             '-r', '__node:=talker'],
            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        t_out, t_err = talker.communicate(timeout=DURATION_S + 40)
        assert talker.returncode == 0, t_err
        l_out, l_err = listener.communicate(timeout=30)
        assert listener.returncode == 0, l_err
    finally:
        for proc in (talker, listener):
            if proc is not None:
                stop_process(proc)
    summary = json.loads(l_out.strip().splitlines()[-1])
    print(f"\n500 Hz JointState(7) over loopback, {summary['received']} msgs: "
          f"p50 {summary['p50_ms']:.3f} ms, p99 {summary['p99_ms']:.3f} ms, "
          f"max {summary['max_ms']:.3f} ms, rate {summary['rate_hz']:.1f} Hz, "
          f"lost {summary['lost']}")
    assert summary['received'] == count
    assert summary['lost'] == 0 and summary['duplicates'] == 0
    # the talker's rclpy timer sets the rate: a wall-clock rate is a benchmark's business
    # (304 Hz seen here while other tests ran); never faster than asked
    assert 0 < summary['rate_hz'] <= RATE_HZ * 1.05


@pytest.mark.backend_pinned
def test_cyclonedds_cli_shows_ros_type_on_rt_topic():
    # the built-in backend's wire format, read by Cyclone's own CLI (Fast DDS 2.14 does not
    # offer XTypes type information, so `cyclonedds typeof` cannot show an rclpy writer's type)
    env = loopback_env(backend='cyclonedds')
    env['COLUMNS'] = '250'
    domain = env['ROS_DOMAIN_ID']
    talker = subprocess.Popen(
        [IFC_SPG, 'ros', 'talker', '--ros-args', '-p', 'rate:=20.0', '-r', '__ns:=/lbr'],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 30
        typeof = ls = ''
        while time.monotonic() < deadline and 'struct JointState_' not in typeof:
            typeof = subprocess.run(
                [CYCLONEDDS, 'typeof', 'rt/lbr/joint_states', '-i', domain, '-r', '2s',
                 '--suppress-progress-bar', '--color', 'none'],
                env=env, capture_output=True, text=True, timeout=30).stdout
        ls = subprocess.run(
            [CYCLONEDDS, 'ls', '-i', domain, '-r', '2s', '-t', 'rt/lbr/joint_states',
             '--suppress-progress-bar', '--color', 'none'],
            env=env, capture_output=True, text=True, timeout=30).stdout
        assert talker.poll() is None, talker.stderr.read()
    finally:
        stop_process(talker)
    assert 'module sensor_msgs' in typeof and 'module dds_' in typeof, typeof
    assert 'struct JointState_' in typeof, typeof
    for line in ('std_msgs::msg::dds_::Header_ header;', 'sequence<string>  name;',
                 'sequence<double>  position;'):
        assert line in typeof, typeof
    assert 'rt/lbr/joint_states' in ls, ls
    assert 'sensor_msgs::msg::dds_::JointState_' in ls, ls


def test_console_script_reports_bad_ros_args_clearly():
    env = loopback_env()
    out = subprocess.run([IFC_SPG, 'ros', 'talker', '--ros-args', '-p', 'rate=5'], env=env,
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 2
    assert "malformed '-p rate=5': expected -p name:=value" in out.stderr
