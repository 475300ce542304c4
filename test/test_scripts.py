"""The launch-free shell scripts in scripts/: shape (STYLE 15), and real runs over loopback DDS
that must stop every process they started."""

import os
import re
import signal
import subprocess
import time
import xml.etree.ElementTree as ET

from helpers import BIN, ROOT, reach_stack, use_loopback
import pytest
from ros_testing import LOOPBACK_CONFIG, loopback_env, stop_process

from ifc_spg import ros
from ifc_spg.ros import msg as ros_msg

SCRIPTS = sorted((ROOT / 'scripts').glob('*.sh'))
RUNNABLE = [p for p in SCRIPTS if p.name != 'lib.sh']
STACK = reach_stack('lbr_iiwa14')


def _env():
    env = loopback_env()
    env['PATH'] = f'{BIN}{os.pathsep}{env["PATH"]}'
    return env


def _run(args, **kwargs):
    """Run a command to completion; stdout/stderr captured as text."""
    return subprocess.run(args, check=False, capture_output=True, text=True, **kwargs)


def _started_pids(text):
    return [int(p) for p in re.findall(r'started \S+ \(PID (\d+)\)', text)]


def _gone(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return False


@pytest.mark.parametrize('script', SCRIPTS, ids=lambda p: p.name)
def test_scripts_say_what_they_do_and_fail_loudly(script):
    text = script.read_text()
    lines = text.splitlines()
    assert _run(['bash', '-n', str(script)]).returncode == 0
    if script.name == 'lib.sh':
        assert lines[0].startswith('# ')  # sourced: a purpose comment, no shebang
        return
    assert lines[0] == '#!/usr/bin/env bash' and lines[1].startswith('# ')
    assert 'set -euo pipefail' in text and os.access(script, os.X_OK)
    assert re.search(r'\$\w+[^"\w]', re.sub(r'"[^"\n]*"|\'[^\'\n]*\'|#.*', '', text)) is None, \
        'unquoted variable expansion'


@pytest.mark.parametrize('script', RUNNABLE, ids=lambda p: p.name)
def test_help_exits_0(script):
    result = _run([str(script), '-h'], env=_env())
    assert result.returncode == 0 and script.name in result.stdout


def test_loopback_xml_is_the_test_config():
    def canon(element):
        return (element.tag, sorted(element.attrib.items()), (element.text or '').strip(),
                [canon(c) for c in element])

    assert canon(ET.parse(ROOT / 'config' / 'cyclonedds_loopback.xml').getroot()) == \
        canon(ET.fromstring(LOOPBACK_CONFIG))


def test_check_stacks_exit_codes(tmp_path):
    good, bad = tmp_path / 'good.yaml', tmp_path / 'bad.yaml'
    good.write_text(STACK)
    bad.write_text(STACK.replace('gain: 5.0', 'gain: -5.0'))
    script = str(ROOT / 'scripts' / 'check_stacks.sh')
    ok = _run([script, str(good)], env=_env())
    assert ok.returncode == 0, ok.stderr
    fail = _run([script, str(good), str(bad)], env=_env())
    assert fail.returncode == 2 and 'bad.yaml' in fail.stderr and 'gain' in fail.stderr


@pytest.mark.ros
def test_publish_stack_delivers_and_exits(tmp_path, monkeypatch):
    env = use_loopback(monkeypatch, _env())
    stack = tmp_path / 'reach.yaml'
    stack.write_text(STACK)
    ros.init(['listener'])
    try:
        node = ros.Node('listener')
        received = []
        node.create_subscription(ros_msg.String, 'spg/task_stack', received.append,
                                 ros.latched(1))
        result = _run([str(ROOT / 'scripts' / 'publish_stack.sh'), '-t', '30', str(stack)],
                      env=env, timeout=60)
        assert result.returncode == 0, result.stderr
        assert ros.spin_until(lambda: received, 5.0, nodes=node)
        assert received[0].data == STACK
    finally:
        ros.shutdown()


@pytest.mark.ros
def test_sim_lbr_lockstep_runs_and_stops_what_it_started(tmp_path):
    stack = tmp_path / 'reach.yaml'
    stack.write_text(STACK)
    out = tmp_path / 'logs'
    result = _run([str(ROOT / 'scripts' / 'sim_lbr.sh'), '-d', '1', '-o', str(out), str(stack)],
                  env=_env(), timeout=120)
    assert result.returncode == 0, result.stderr
    assert re.search(r'spg_node: 500 ticks, 500 commands', result.stdout), result.stdout
    pids = _started_pids(result.stderr)
    assert len(pids) == 3 and all(_gone(p) for p in pids)
    assert "task stack 'reach' (id 1) accepted" in (out / 'spg_node.log').read_text()


@pytest.mark.realtime
@pytest.mark.ros
def test_sim_lbr_trap_stops_its_processes_on_sigterm(tmp_path):
    out = tmp_path / 'logs'
    proc = subprocess.Popen([str(ROOT / 'scripts' / 'sim_lbr.sh'), '-m', 'realtime', '-d',
                             '60', '-o', str(out)], stderr=subprocess.PIPE, text=True,
                            env=_env())
    err = ''
    try:
        deadline = time.monotonic() + 60
        while len(_started_pids(err)) < 2 and time.monotonic() < deadline:
            line = proc.stderr.readline()
            assert line, f'script ended early: {err}'
            err += line
        pids = _started_pids(err)
        assert len(pids) == 2  # spg_node, sim_bridge
        proc.send_signal(signal.SIGTERM)
        err += proc.stderr.read()
        assert proc.wait(timeout=30) == 130
    finally:
        stop_process(proc, timeout=10)
    assert all(_gone(p) for p in pids), err
    assert err.count('stopped PID') == 2
