"""Test helpers: loopback-only DDS, a random ROS domain, child processes.

A loopback-only DDS configuration for both backends, a random ROS domain, and child
processes started (and stopped, by PID) from a test.

    env = loopback_env()            # for subprocesses: CYCLONEDDS_URI, ROS_DOMAIN_ID, ...
    env = loopback_env(backend='cyclonedds')   # children on the built-in backend
    monkeypatch.setenv(...)         # or apply LOOPBACK_KEYS to the current process in a test
    procs = ProcessGroup(tmp_path, env)   # console scripts logging to tmp_path/<name>.log

Cyclone binds to ``lo`` only (``lo`` has no MULTICAST flag, so multicast is switched off and the
participants find each other by unicast to 127.0.0.1); rclpy on Fast DDS is kept on the host
by ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` (unicast discovery to 127.0.0.1, no multicast).
Both use the standard RTPS port mapping, so the two vendors find each other on one domain.
"""

import os
from pathlib import Path
import random
import signal
import subprocess
import sys

from ifc_spg.ros.stamps import stamp_to_ns

__all__ = ['LOOPBACK_CONFIG', 'LOOPBACK_KEYS', 'ProcessGroup', 'loopback_env',
           'raise_priority', 'random_domain_id', 'stamp_ns', 'stop_process']

LOOPBACK_CONFIG = (
    '<CycloneDDS><Domain Id="any"><General>'
    '<Interfaces><NetworkInterface name="lo" multicast="false"/></Interfaces>'
    '<AllowMulticast>false</AllowMulticast></General>'
    '<Discovery><ParticipantIndex>auto</ParticipantIndex>'
    '<MaxAutoParticipantIndex>30</MaxAutoParticipantIndex>'
    '<Peers><Peer address="127.0.0.1"/></Peers></Discovery>'
    '</Domain></CycloneDDS>')
# the environment variables :func:`loopback_env` sets
LOOPBACK_KEYS = ('CYCLONEDDS_URI', 'ROS_DOMAIN_ID', 'IFC_SPG_ROS_BACKEND',
                 'ROS_AUTOMATIC_DISCOVERY_RANGE', 'ROS_STATIC_PEERS',
                 'FASTDDS_DEFAULT_PROFILES_FILE', 'FASTRTPS_DEFAULT_PROFILES_FILE')


def _fastdds_profile():
    """config/fastdds_loopback.xml of the checkout, else of the installed share/ifc_spg."""
    for root in (Path(__file__).resolve().parents[1], Path(sys.prefix) / 'share' / 'ifc_spg'):
        path = root / 'config' / 'fastdds_loopback.xml'
        if path.is_file():
            return str(path)
    return ''


# Fast DDS on loopback: ports on 127.0.0.1, 32 participant indices, an announcement every
# second (the file says what it does, and that rmw_fastrtps adds shared memory under LOCALHOST)
FASTDDS_PROFILE = _fastdds_profile()


def random_domain_id(rng=None):
    """A ROS domain id in [1, 101] (0 is everybody's default), from ``rng`` or os.urandom.

    ``IFC_SPG_TEST_DOMAIN_SLOT=J/M`` keeps a test session to the ids with ``id % M == J``
    (./run test runs the rclpy and the built-in backend's sessions side by side); within
    them, under pytest-xdist (``PYTEST_XDIST_WORKER`` gwK of ``PYTEST_XDIST_WORKER_COUNT``
    N), each worker gets the ids with ``(id // M) % N == K``: tests running at the same time
    never share a domain, whatever each session's worker count.
    """
    rng = rng or random.Random(os.urandom(8))
    worker = os.environ.get('PYTEST_XDIST_WORKER', '')
    count = int(os.environ.get('PYTEST_XDIST_WORKER_COUNT', '1') or 1)
    k = int(worker[2:]) % count if worker.startswith('gw') and worker[2:].isdigit() else 0
    slot, slots = _domain_slot()
    ids = [d for d in range(1, 102) if d % slots == slot and (d // slots) % count == k]
    return rng.choice(ids)


def _domain_slot():
    """``(J, M)`` from ``IFC_SPG_TEST_DOMAIN_SLOT=J/M`` (default ``(0, 1)``: every id)."""
    text = os.environ.get('IFC_SPG_TEST_DOMAIN_SLOT', '').strip()
    if not text:
        return 0, 1
    try:
        slot, slots = (int(x) for x in text.split('/'))
    except ValueError:
        slot, slots = -1, 0
    if not 0 <= slot < slots <= 8:
        raise ValueError(f"IFC_SPG_TEST_DOMAIN_SLOT='{text}' is not J/M with 0 <= J < M <= 8")
    return slot, slots


def loopback_env(domain_id=None, base=None, backend=None):
    """A copy of ``base`` (default os.environ) on loopback, on one ROS domain.

    Args:
        domain_id: the ROS domain; None: a random one.
        base: the environment to copy.
        backend: 'rclpy' or 'cyclonedds' for the processes started with it; None: the
            backend this process runs (``ifc_spg.ros.BACKEND``).
    """
    if backend is None:
        from ifc_spg import ros
        backend = ros.BACKEND
    if backend not in ('rclpy', 'cyclonedds'):
        raise ValueError(f"backend '{backend}' is not 'rclpy' or 'cyclonedds'")
    env = dict(os.environ if base is None else base)
    env['CYCLONEDDS_URI'] = LOOPBACK_CONFIG
    env['ROS_DOMAIN_ID'] = str(random_domain_id() if domain_id is None else domain_id)
    env['IFC_SPG_ROS_BACKEND'] = backend
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env['ROS_STATIC_PEERS'] = ''
    env['FASTDDS_DEFAULT_PROFILES_FILE'] = FASTDDS_PROFILE
    env['FASTRTPS_DEFAULT_PROFILES_FILE'] = FASTDDS_PROFILE   # the Fast DDS 2.x name
    return env


#: The nice value :func:`raise_priority` gives a child (IFC_SPG_TEST_NICE overrides; 0: off).
CHILD_NICE = -10


def raise_priority():
    """Run this (child) process at nice :data:`CHILD_NICE` where permitted (root), else as is.

    A realtime loop on a shared machine needs priority, as on a robot PC (``chrt``, nice): at
    nice 0 beside other CPU-heavy processes (load 7 on 2 cores) the SPG's 2 ms timer fired at
    200-270 Hz. Children started by :class:`ProcessGroup` call it before they run.
    """
    nice = int(os.environ.get('IFC_SPG_TEST_NICE', CHILD_NICE))
    if nice:
        try:
            os.setpriority(os.PRIO_PROCESS, 0, nice)
        except OSError:  # not permitted (no root, no CAP_SYS_NICE): keep the inherited value
            pass


def stop_process(proc, timeout=5.0, sig=signal.SIGTERM):
    """Stop a child process we started (by its PID) and reap it.

    Args:
        proc: a :class:`subprocess.Popen`.
        timeout: how long to wait [s] after ``sig``, and again after SIGKILL.
        sig: the signal sent first (SIGKILL follows if the child does not exit in time).

    Returns:
        The child's exit code (``-signal`` if a signal ended it).
    """
    if proc.poll() is None:
        proc.send_signal(sig)
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=timeout)
    return proc.returncode


def stamp_ns(msg):
    """The ``header.stamp`` of a stamped message as an int [ns]."""
    return stamp_to_ns(msg.header.stamp)


class ProcessGroup:
    """Child processes of one test, each logging (stdout and stderr) to ``<name>.log``.

    Args:
        log_dir: folder of the log files.
        env: environment of the children (e.g. :func:`loopback_env`).
        bin_dir: folder of the console scripts; default: the running interpreter's.
    """

    def __init__(self, log_dir, env, bin_dir=None):
        self.log_dir, self.env = Path(log_dir), env
        self.bin_dir = Path(sys.executable).parent if bin_dir is None else Path(bin_dir)
        self.procs, self.logs = {}, {}

    def start(self, name, *args, exe=None, env=None):
        """Start console script ``exe`` (default ``name``; ``'python'``: this interpreter),
        with ``env`` (default: the group's).

        Returns:
            The :class:`subprocess.Popen`, also kept as ``procs[name]``.
        """
        self.logs[name] = open(self.log_dir / f'{name}.log', 'w+')
        cmd = [sys.executable] if exe == 'python' else [str(self.bin_dir / (exe or name))]
        self.procs[name] = subprocess.Popen([*cmd, *args], env=self.env if env is None else env,
                                            stdout=self.logs[name], stderr=subprocess.STDOUT,
                                            preexec_fn=raise_priority)
        return self.procs[name]

    def log(self, name):
        """Everything child ``name`` has written so far (also after :meth:`close`)."""
        if not self.logs[name].closed:
            self.logs[name].flush()
        return (self.log_dir / f'{name}.log').read_text()

    def stop(self, name, sig=signal.SIGTERM, timeout=15.0):
        """Stop child ``name`` with ``sig`` (SIGKILL after ``timeout`` [s]); its exit code."""
        return stop_process(self.procs[name], timeout=timeout, sig=sig)

    def close(self, sig=signal.SIGTERM, timeout=5.0):
        """Stop every child still running, the last started first, and close the logs."""
        for proc in reversed(list(self.procs.values())):
            stop_process(proc, timeout=timeout, sig=sig)
        for f in self.logs.values():
            f.close()
