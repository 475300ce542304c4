"""Plots: one PNG per task plus joints, contact force, torques, tanks, timing; an index."""

import re

import pytest

from ifc_spg.cli.plot import main
from ifc_spg.offline.runner import find_config_dir, load_scenario, run_scenario


@pytest.fixture(scope='module')
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp('plot')
    sc = load_scenario(find_config_dir() / 'scenarios' / 'surface_short.yaml',
                       {'duration': 1.1, 'spg': {'status_decimation': 5}})
    return run_scenario(sc, out, quiet=True)


def test_pngs_and_index(run, tmp_path):
    out = tmp_path / 'plots'
    assert main([str(run.bag), '-o', str(out)]) == 0
    expected = {'task_contact_force.png', 'task_hold.png', 'task_circle.png',
                'task_posture.png', 'joints.png', 'contact_force.png', 'torques.png',
                'tanks.png', 'timing.png'}
    pngs = {p.name for p in out.glob('*.png')}
    assert pngs == expected
    for name in pngs:
        data = (out / name).read_bytes()
        assert data[:8] == b'\x89PNG\r\n\x1a\n' and len(data) > 10_000
    index = (out / 'index.html').read_text()
    assert set(re.findall(r'<img src="([^"]+)"', index)) == expected
    assert '"limit_violations"' in index  # metrics.json next to the bag is shown
