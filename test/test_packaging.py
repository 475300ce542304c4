"""Every install route builds the C kernels: ``pip wheel .`` with build isolation (setup.py
cannot import numpy from the caller's environment there; pyproject.toml's [build-system]
provides it) holds both extensions, and not the workshop (benchmarks, tests)."""

from pathlib import Path
import shutil
import subprocess
import sys
import zipfile

from helpers import ROOT
import pytest

pytestmark = pytest.mark.slow


def test_isolated_wheel_build_carries_both_c_extensions(tmp_path):
    # from a copy without build products: setuptools packs whatever an earlier build left
    # in build/lib (a checkout built before files moved put them in the wheel)
    src = tmp_path / 'src'
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(
        '.git', '.venv', 'build', 'out', '*.egg-info', '*.so', '__pycache__'))
    out = subprocess.run([sys.executable, '-m', 'pip', 'wheel', '--no-deps',
                          '--disable-pip-version-check', '-q', '-w', str(tmp_path),
                          str(src)], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    (wheel,) = Path(tmp_path).glob('ifc_spg-*.whl')
    names = zipfile.ZipFile(wheel).namelist()
    for module in ('ifc_spg/kernels/_native', 'ifc_spg/dynamics/_native_dynamics'):
        assert any(n.startswith(module) and n.endswith('.so') for n in names), \
            (module, [n for n in names if n.endswith('.so')])
    # the workshop stays out of the wheel: benchmarks (and KDL's C++ timing program), tests
    assert not [n for n in names if n.split('/')[0] in ('benchmarks', 'test', 'experiments')
                or n.endswith('.cpp')]
    assert any(n.startswith('ifc_spg/cli/') for n in names)
