"""Test sessions that run at the same time never share a ROS domain (ros_testing)."""

import random

import pytest
from ros_testing import random_domain_id


def _ids(monkeypatch, worker, count, slot):
    monkeypatch.setenv('PYTEST_XDIST_WORKER', worker)
    monkeypatch.setenv('PYTEST_XDIST_WORKER_COUNT', str(count))
    monkeypatch.setenv('IFC_SPG_TEST_DOMAIN_SLOT', slot)
    rng = random.Random(7)
    return {random_domain_id(rng) for _ in range(2000)}


@pytest.mark.parametrize('count', [1, 2, 4])
def test_workers_and_slots_get_disjoint_domains(monkeypatch, count):
    seen = {}
    for k in range(count):
        for slot in ('0/2', '1/2'):
            ids = _ids(monkeypatch, f'gw{k}', count, slot)
            assert ids and all(1 <= d <= 101 for d in ids)
            for other, theirs in seen.items():
                assert not ids & theirs, (k, slot, other)
            seen[(k, slot)] = ids
    # together they still cover every id
    assert set().union(*seen.values()) == set(range(1, 102))


@pytest.mark.parametrize('count', [2, 4])
def test_slots_stay_disjoint_across_worker_counts(monkeypatch, count):
    """./run test: rclpy's realtime session (slot 0/2, no workers) beside the built-in
    backend's sessions (slot 1/2, one at a time, then N workers)."""
    alone = _ids(monkeypatch, '', 1, '0/2')
    others = set().union(*(_ids(monkeypatch, f'gw{k}', count, '1/2') for k in range(count)),
                         _ids(monkeypatch, '', 1, '1/2'))
    assert alone and others and not alone & others


@pytest.mark.parametrize('bad', ['2/2', '1', 'a/b', '0/9'])
def test_a_bad_slot_is_named(monkeypatch, bad):
    monkeypatch.setenv('IFC_SPG_TEST_DOMAIN_SLOT', bad)
    with pytest.raises(ValueError, match='IFC_SPG_TEST_DOMAIN_SLOT'):
        random_domain_id()
