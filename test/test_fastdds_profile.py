"""What ``config/fastdds_loopback.xml`` does to an rclpy participant under the loopback
settings the tests, ``scripts/lib.sh`` and the README use (``ROS_AUTOMATIC_DISCOVERY_RANGE=
LOCALHOST``): the domain's well-known ports (discovery and user traffic) listen on 127.0.0.1
only — without the profile they listen on every interface — and user data goes over UDP on
127.0.0.1, not through a shared-memory port: rmw_fastrtps_cpp's LOCALHOST setting adds Fast
DDS' shared-memory transport whatever the profile says, and without the profile the
participant opens a shared-memory port (a segment ``/dev/shm/fastrtps_port<N>``) for its
data. Linux /proc only."""

import os
from pathlib import Path
import socket
import struct
import subprocess
import sys

import pytest
from ros_testing import FASTDDS_PROFILE, loopback_env, stop_process

pytestmark = [pytest.mark.dds, pytest.mark.ros, pytest.mark.backend_pinned]

CHILD = """
import sys, time, rclpy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node('profile_probe')
pub = node.create_publisher(String, 'probe', 10)
sub = node.create_subscription(String, 'probe', lambda m: None, 10)
print('ready', flush=True)
sys.stdin.read()  # until the test closes it
node.destroy_node()
rclpy.shutdown()
"""

# RTPS well-known ports (RTPS 2.2, 9.6.1.1): PB 7400 + DG 250 x domain + offsets < 250
PB, DG = 7400, 250


def _udp_sockets(pid):
    """``(address, port)`` of the UDP sockets process ``pid`` holds (IPv4)."""
    inodes = set()
    for fd in Path(f'/proc/{pid}/fd').iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith('socket:['):
            inodes.add(target[8:-1])
    found = []
    for line in Path(f'/proc/{pid}/net/udp').read_text().splitlines()[1:]:
        fields = line.split()
        if fields[9] in inodes:
            addr, port = fields[1].split(':')
            ip = socket.inet_ntoa(struct.pack('<I', int(addr, 16)))
            found.append((ip, int(port, 16)))
    return found


def _probe(env):
    """Start a participant with ``env``; its UDP sockets and /dev/shm mappings."""
    proc = subprocess.Popen([sys.executable, '-c', CHILD], env=env, stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    try:
        lines = []
        while not lines or lines[-1].strip() != 'ready':
            lines.append(proc.stdout.readline())
            assert lines[-1], ''.join(lines)  # ended before it was ready
        sockets = _udp_sockets(proc.pid)
        maps = [ln.split()[-1] for ln in Path(f'/proc/{proc.pid}/maps').read_text().splitlines()
                if '/dev/shm/fastrtps_' in ln]
    finally:
        proc.stdin.close()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            stop_process(proc)
    return sockets, maps


@pytest.mark.skipif(not sys.platform.startswith('linux'), reason='reads Linux /proc')
def test_profile_keeps_the_domain_ports_on_loopback_and_data_off_shared_memory():
    pytest.importorskip('rclpy', reason='rclpy (the ros-jazzy wheels) is not installed')
    assert FASTDDS_PROFILE, 'config/fastdds_loopback.xml not found'
    env = loopback_env(backend='rclpy')
    env['RMW_IMPLEMENTATION'] = 'rmw_fastrtps_cpp'
    domain = int(env['ROS_DOMAIN_ID'])
    base = PB + DG * domain

    def on_domain_ports(sockets):
        return [(ip, port) for ip, port in sockets if base <= port < base + DG]

    sockets, maps = _probe(env)
    ports = on_domain_ports(sockets)
    assert ports, sockets  # the participant listens on its domain's ports
    assert {ip for ip, _ in ports} == {'127.0.0.1'}, ports
    assert not [m for m in maps if '/fastrtps_port' in m], maps  # no shared-memory port
    # without the profile the same ports listen on every interface and the data port is a
    # shared-memory one too: the profile is what keeps them on loopback and off SHM
    bare = {k: v for k, v in env.items()
            if k not in ('FASTDDS_DEFAULT_PROFILES_FILE', 'FASTRTPS_DEFAULT_PROFILES_FILE')}
    bare_sockets, bare_maps = _probe(bare)
    bare_ports = on_domain_ports(bare_sockets)
    assert '0.0.0.0' in {ip for ip, _ in bare_ports}, bare_ports
    assert [m for m in bare_maps if '/fastrtps_port' in m], bare_maps
