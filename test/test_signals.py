"""Clean shutdown of every executable on SIGINT and SIGTERM, at any moment of its life.

Each program is started as a non-interactive shell starts its background jobs: with SIGINT
*ignored* (what made a Ctrl-C during the first second of ``spg_node`` get lost). The signal
goes out at several points: as soon as the program's entry point has installed its handlers
(read from ``/proc/PID/status``, so the test does not guess a time), a moment later (imports,
model build, DDS start-up), and after its start-up line. Every run must end by itself with exit
status 0, print no traceback, and say why it stopped (a start-up message or the program's
summary line).
"""

from pathlib import Path
import signal
import subprocess
import time

from helpers import BIN, CONFIG, reach_stack, use_loopback, wait_for
import pytest
from ros_testing import stop_process

pytestmark = [pytest.mark.dds, pytest.mark.ros, pytest.mark.realtime]

SIGNALS = (signal.SIGINT, signal.SIGTERM)
_BITS = (1 << (signal.SIGINT - 1)) | (1 << (signal.SIGTERM - 1))


def _catches_both(pid):
    """True once process ``pid`` has handlers for SIGINT and SIGTERM (SigCgt of /proc)."""
    try:
        for line in Path(f'/proc/{pid}/status').read_text().splitlines():
            if line.startswith('SigCgt:'):
                return int(line.split()[1], 16) & _BITS == _BITS
    except OSError:
        return False
    return False


def _ignore_sigint():
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _programs(tmp_path):
    stack = tmp_path / 'reach.yaml'
    stack.write_text(reach_stack('lbr_iiwa14'))
    return {
        'spg_node': ([str(BIN / 'spg_node'), '--ros-args', '--params-file',
                      str(CONFIG / 'lbr_iiwa14.yaml')], 'waiting for joint_states'),
        'sim_bridge': ([str(BIN / 'sim_bridge'), '--ros-args', '-p', 'robot:=lbr_iiwa14',
                        '-p', 'scene:=free', '-p', 'mode:=realtime'], 'sim_bridge'),
        'task_publisher': ([str(BIN / 'task_publisher'), str(stack)], 'task_publisher'),
        'bag_record': ([str(BIN / 'ifc-spg'), 'bag', 'record', '-o', '{run}'], 'recording'),
    }


@pytest.mark.skipif(not Path('/proc/self/status').exists(), reason='needs /proc (Linux)')
@pytest.mark.parametrize('name', ['spg_node', 'sim_bridge', 'task_publisher', 'bag_record'])
def test_a_signal_at_any_moment_ends_the_program_cleanly(name, tmp_path, monkeypatch):
    env = use_loopback(monkeypatch)
    cmd, started_line = _programs(tmp_path)[name]
    moments = ['handlers', 'handlers+0.5s', 'started']
    for sig in SIGNALS:
        for moment in moments:
            log = tmp_path / f'{name}-{sig.name}-{moment}.log'
            run = str(tmp_path / f'{sig.name}-{moment}')
            with open(log, 'w') as out:
                proc = subprocess.Popen([a.format(run=run) for a in cmd], env=env, stdout=out,
                                        stderr=subprocess.STDOUT, preexec_fn=_ignore_sigint,
                                        cwd=tmp_path)
            try:
                assert wait_for(lambda p=proc: _catches_both(p.pid) or p.poll() is not None,
                                60), log.read_text()
                if moment == 'handlers+0.5s':
                    time.sleep(0.5)
                elif moment == 'started':
                    assert wait_for(lambda p=proc, f=log: started_line in f.read_text()
                                    or p.poll() is not None, 90), log.read_text()
                assert proc.poll() is None, (moment, log.read_text())
                proc.send_signal(sig)
                assert wait_for(lambda p=proc: p.poll() is not None, 60), \
                    f'{name} still runs 60 s after {sig.name} ({moment}):\n{log.read_text()}'
            finally:
                stop_process(proc, timeout=5, sig=signal.SIGKILL)
            text = log.read_text()
            where = f'{name}, {sig.name} at {moment}:\n{text}'
            assert proc.returncode == 0, where
            assert 'Traceback' not in text, where
            assert text.strip(), where   # it said why it stopped
