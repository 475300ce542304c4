"""Test helpers: a loopback-only Cyclone DDS configuration and a random ROS domain.

    env = loopback_env()            # for subprocesses: CYCLONEDDS_URI + ROS_DOMAIN_ID
    monkeypatch.setenv(...)         # or apply to the current process in a test

Cyclone binds to ``lo`` only (``lo`` has no MULTICAST flag, so multicast is switched off and the
participants find each other by unicast to 127.0.0.1).
"""

import os
import random
import subprocess

__all__ = ['LOOPBACK_CONFIG', 'loopback_env', 'random_domain_id', 'stop_process']

LOOPBACK_CONFIG = (
    '<CycloneDDS><Domain Id="any"><General>'
    '<Interfaces><NetworkInterface name="lo" multicast="false"/></Interfaces>'
    '<AllowMulticast>false</AllowMulticast></General>'
    '<Discovery><ParticipantIndex>auto</ParticipantIndex>'
    '<MaxAutoParticipantIndex>30</MaxAutoParticipantIndex>'
    '<Peers><Peer address="127.0.0.1"/></Peers></Discovery>'
    '</Domain></CycloneDDS>')


def random_domain_id(rng=None):
    """A ROS domain id in [1, 101] (0 is everybody's default), from ``rng`` or os.urandom."""
    rng = rng or random.Random(os.urandom(8))
    return rng.randint(1, 101)


def loopback_env(domain_id=None, base=None):
    """A copy of ``base`` (default os.environ) with CYCLONEDDS_URI and ROS_DOMAIN_ID set."""
    env = dict(os.environ if base is None else base)
    env['CYCLONEDDS_URI'] = LOOPBACK_CONFIG
    env['ROS_DOMAIN_ID'] = str(random_domain_id() if domain_id is None else domain_id)
    env['IFC_SPG_ROS_BACKEND'] = 'cyclonedds'
    return env


def stop_process(proc, timeout=5.0):
    """Terminate a child process we started (by its PID), reap it; return its exit code."""
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=timeout)
    return proc.returncode
