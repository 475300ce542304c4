"""The package builds as a ROS 2 ament_python package with colcon (issue 2, item 4)."""

import os
import shutil
import subprocess
import sys

import pytest

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.mark.slow
def test_colcon_build_installs_executables_and_ament_marker(tmp_path):
    colcon = os.path.join(os.path.dirname(sys.executable), 'colcon')
    assert os.path.exists(colcon), 'colcon-core is pinned in requirements.txt'
    src = tmp_path / 'src' / 'ifc_spg'
    shutil.copytree(REPO, src, ignore=shutil.ignore_patterns(
        '.venv', '.git', 'out', 'build', 'install', 'log', '*.egg-info', '__pycache__',
        '.pytest_cache', '.hypothesis'))
    env = dict(os.environ, COLCON_HOME=str(tmp_path / 'colcon_home'))
    proc = subprocess.run([colcon, 'build', '--base-paths', str(tmp_path / 'src')],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    print(proc.stdout[-2000:], proc.stderr[-2000:])
    assert proc.returncode == 0, proc.stderr
    install = tmp_path / 'install' / 'ifc_spg'
    for exe in ('spg_node', 'sim_bridge', 'task_publisher', 'ifc-spg'):
        assert (install / 'lib' / 'ifc_spg' / exe).is_file(), exe
    index = install / 'share' / 'ament_index' / 'resource_index' / 'packages'
    assert (index / 'ifc_spg').is_file()
    assert (install / 'share' / 'ifc_spg' / 'package.xml').is_file()
    assert (install / 'share' / 'ifc_spg' / 'config' / 'lbr_iiwa14.yaml').is_file()
    site = next((install / 'lib').glob('python3*/site-packages'))
    assert (site / 'ifc_spg' / 'model' / 'data' / 'lbr_iiwa14.xml').is_file()
    assert list((site / 'ifc_spg' / 'kernels').glob('_native*.so')), \
        'the C kernels are built and installed'
    # spg_node --help runs from the colcon install (what `source install/setup.bash` sets up)
    run_env = dict(os.environ, PYTHONPATH=str(site))
    out = subprocess.run([str(install / 'lib' / 'ifc_spg' / 'spg_node'), '--help'],
                         env=run_env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert 'spg_node' in out.stdout
