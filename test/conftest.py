"""Shared fixtures; test helper modules in this folder are importable by name, and the
checkout's ``benchmarks`` package (not installed with ifc_spg) by its name."""

import os
import sys

import pytest

# as the executables run (ifc_spg.entry): one BLAS thread, for the test processes and the
# processes they start (set before anything imports numpy)
os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')
sys.path.insert(0, os.path.dirname(__file__))
sys.path.append(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from helpers import use_loopback  # noqa: E402 (needs the path above)


@pytest.fixture
def dds_env(monkeypatch):
    """This test on its own loopback DDS domain: the environment (also for child processes);
    the active backend's default context and the built-in backend's (tests of the built-in
    backend itself use it directly, also where rclpy is active) are shut down afterwards."""
    from ifc_spg import ros
    from ifc_spg.ros import dds

    env = use_loopback(monkeypatch)
    yield env
    ros.shutdown()
    dds.shutdown()


@pytest.fixture
def domain(dds_env):
    """This test's ROS domain id, on loopback (see ``dds_env``)."""
    return int(dds_env['ROS_DOMAIN_ID'])


@pytest.fixture(params=['native', 'numpy'])
def impl(request, monkeypatch):
    """Run this test with the C kernels of the 2 ms path and with their numpy reference
    (objects created in the test take ``ifc_spg.kernels.active`` as their default)."""
    from ifc_spg import kernels
    if request.param == 'numpy':
        monkeypatch.setattr(kernels, 'active', kernels.reference)
    return request.param


def pytest_collection_modifyitems(config, items):
    """The ``slow`` tests first, in their collected order, then the rest as collected.

    pytest-xdist's worksteal scheduler hands each worker a contiguous share of this order and
    lets an idle worker take pending tests from the end of another's queue: with the long
    tests at the front, the pass ends on short ones instead of one worker finishing a minute
    of lockstep DDS while the other waits.
    """
    items.sort(key=lambda item: item.get_closest_marker('slow') is None)
