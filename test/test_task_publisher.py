"""Tests of ``task_publisher``: validation like ``ifc-spg check``, latched delivery, timed
sequences, exit codes (in-process and as a process, loopback DDS, own domain)."""

from pathlib import Path
import re
import subprocess
import time

from helpers import BIN, reach_stack
import pytest
from ros_testing import stop_process

from ifc_spg import ros
from ifc_spg.cli.check import main as check_main
from ifc_spg.cli.task_publisher import main
from ifc_spg.errors import IfcSpgError
from ifc_spg.node.task_publisher import parse_entry
from ifc_spg.ros import msg as ros_msg

pytestmark = [pytest.mark.dds, pytest.mark.ros]

STACK = reach_stack('lbr_iiwa14', name='{name}')


def _file(tmp_path, name, text=None):
    path = tmp_path / f'{name}.yaml'
    path.write_text(STACK.format(name=name) if text is None else text)
    return str(path)



class Listener:
    """A subscription on spg/task_stack in its own context (own DDS participant)."""

    def __init__(self):
        self.context = ros.new_context(['listener'])
        self.node = ros.Node('listener', context=self.context)
        self.received = []
        self.node.create_subscription(ros_msg.String, 'spg/task_stack',
                                      lambda m: self.received.append((time.monotonic(),
                                                                      m.data)), ros.latched(1))

    def spin_until(self, condition, timeout):
        return ros.spin_until(condition, timeout, nodes=self.node)

    def close(self):
        ros.shutdown(context=self.context)


@pytest.mark.parametrize('entry, expected', [
    ('a.yaml', ('a.yaml', 0.0)), ('a.yaml@2.5', ('a.yaml', 2.5)),
    ('dir@x/a.yaml@3', ('dir@x/a.yaml', 3.0)), ('a.yaml@0', ('a.yaml', 0.0))])
def test_parse_entry(entry, expected):
    assert parse_entry(entry) == expected


@pytest.mark.parametrize('entry', ['a.yaml@x', 'a.yaml@-1', 'a.yaml@inf', 'a.yaml@nan'])
def test_parse_entry_rejects_bad_times(entry):
    with pytest.raises(IfcSpgError, match="the time after '@'"):
        parse_entry(entry)


@pytest.mark.parametrize('edit', [
    lambda s: s.replace('joint_position', 'joint_positon'),         # unknown type
    lambda s: s.replace('0.3, 0.7, 0.2, ', '0.3, '),                  # wrong dimension
    lambda s: s.replace('robot: lbr_iiwa14', 'robot: lbr_iiwa'),     # unknown robot
    lambda s: s.replace('gain: 5.0', 'gain: .nan'),                  # NaN
])
def test_invalid_files_exit_2_with_the_messages_of_ifc_spg_check(tmp_path, capsys, edit):
    good = _file(tmp_path, 'good')
    bad = _file(tmp_path, 'bad', edit(STACK.format(name='bad')))
    assert main(['task_publisher', good, f'{bad}@1', '--once']) == 2
    err = capsys.readouterr().err
    assert check_main([bad]) == 2
    expected = capsys.readouterr().err
    assert err == expected and bad in err and 'line' in err


def test_unreadable_file_and_bad_options_exit_2(tmp_path, capsys):
    assert main(['task_publisher', str(tmp_path / 'missing.yaml')]) == 2
    assert 'missing.yaml' in capsys.readouterr().err
    assert main(['task_publisher', _file(tmp_path, 'a'), '--linger', '-1']) == 2
    assert main(['task_publisher']) == 2


def test_once_waits_for_a_subscriber_and_delivers(tmp_path, dds_env):
    path = _file(tmp_path, 'reach')
    listener = Listener()
    try:
        assert main(['task_publisher', path, '--once', '--timeout', '20']) == 0
        assert listener.spin_until(lambda: listener.received, 5.0)
        assert [text for _, text in listener.received] == [Path(path).read_text()]
    finally:
        listener.close()


def test_once_without_subscriber_exits_1(tmp_path, dds_env):
    assert main(['task_publisher', _file(tmp_path, 'a'), '--once', '--timeout', '0.3']) == 1


@pytest.mark.realtime
def test_timed_sequence_and_latched_delivery_to_a_late_subscriber(tmp_path, dds_env):
    a, b = _file(tmp_path, 'first'), _file(tmp_path, 'second')
    listener = Listener()
    # --linger 5: a late joiner needs the publisher alive until it is discovered (Fast DDS
    # can take one 3 s announcement period for a new participant)
    proc = subprocess.Popen([str(BIN / 'task_publisher'), f'{b}@0.8', a,
                             '--wait-subscribers', '1', '--linger', '5.0'],
                            env=dds_env, stderr=subprocess.PIPE, text=True)
    late = None
    try:
        assert listener.spin_until(lambda: len(listener.received) == 2, 30.0), \
            proc.stderr.read() if proc.poll() is not None else ''
        (t_a, text_a), (t_b, text_b) = listener.received
        assert 'name: first' in text_a and 'name: second' in text_b
        assert t_a <= t_b  # in order (their receipt spacing is the machine's: a loaded one
        # delivered the first late, 0.34 s before the second)
        late = Listener()  # joins after both: the latched topic gives it the latest only
        assert late.spin_until(lambda: late.received, 10.0)
        assert [text for _, text in late.received] == [text_b]
        assert proc.wait(timeout=15) == 0  # --linger 5 s after the last one
        log = proc.stderr.read()
        # each at its time after the start on the publisher's own clock, 0 and 0.8 s (never
        # earlier; later by its 20 ms poll plus what the machine adds). The log's time is
        # taken after the publish: a loaded run printed +0.007 and +0.802, 0.795 s apart
        at = [float(x) for x in re.findall(r"published '[^']*' \(stack '[^']*'\) on \S+ at "
                                           r'\+([0-9.]+) s', log)]
        assert len(at) == 2, log
        assert 0.0 <= at[0] <= 2.2 and 0.8 <= at[1] <= 3.0 and at[0] < at[1], at
    finally:
        stop_process(proc)
        listener.close()
        if late is not None:
            late.close()


def test_stays_alive_until_sigterm_and_exits_0(tmp_path, dds_env):
    listener = Listener()
    proc = subprocess.Popen([str(BIN / 'task_publisher'), _file(tmp_path, 'a')], env=dds_env,
                            stderr=subprocess.DEVNULL)
    try:
        assert listener.spin_until(lambda: listener.received, 30.0)
        time.sleep(0.3)  # let time pass: without --linger it must not exit by itself
        assert proc.poll() is None
    finally:
        code = stop_process(proc)
        listener.close()
    assert code == 0
