"""The command lines in ifc_spg/cli/: ``python -m ifc_spg.cli`` is ``ifc-spg``; the bench verbs
run the checkout's benchmarks/ and say so where there is none (a wheel install)."""

import subprocess
import sys

from helpers import ROOT

from ifc_spg import cli
from ifc_spg.cli import bench, dynamics


def test_python_m_ifc_spg_cli_is_the_ifc_spg_dispatcher():
    out = subprocess.run([sys.executable, '-m', 'ifc_spg.cli'], capture_output=True, text=True,
                         cwd=ROOT, timeout=60)
    assert out.returncode == 2
    assert all(f'  {verb} ' in out.stdout for verb in cli.VERBS)


def test_the_bench_verbs_find_the_checkouts_benchmarks():
    assert bench.BENCHMARKS == ROOT / 'benchmarks'
    module = bench.benchmark_module('dynamics_bench')
    assert module is not None and callable(module.main)


def test_without_benchmarks_next_to_the_package_the_bench_verbs_say_so(tmp_path, monkeypatch,
                                                                       capsys):
    monkeypatch.setattr(bench, 'BENCHMARKS', tmp_path / 'benchmarks')
    assert bench.main(['--quick']) == 2
    err = capsys.readouterr().err
    assert 'not installed with the package' in err and 'python -m benchmarks.bench' in err
    assert dynamics.main(['bench', '--quick']) == 2
    err = capsys.readouterr().err
    assert err.startswith('ifc-spg dynamics bench:') and 'benchmarks.dynamics_bench' in err
