"""The console entry points (ifc_spg/entry.py): MuJoCo without a GL backend where nothing renders.

With ``MUJOCO_GL`` unset, importing MuJoCo loads GLFW, whose import starts a Python child to
read the library's version; a signal during a program's start-up then left the child writing
into a closed pipe (a BrokenPipeError traceback in ``ifc-spg bag record``'s output, seen in
test_signals). The programs that never render import MuJoCo without GL; ``render`` and
``demo`` keep it, and a ``MUJOCO_GL`` the user set is kept.
"""

import json
import os
import subprocess
import sys

import pytest

PROBE = """
import json, os, sys
def main():
    import mujoco  # noqa: F401
    print(json.dumps({'glfw': 'glfw' in sys.modules, 'gl': os.environ.get('MUJOCO_GL')}))
"""


def _probe(tmp_path, call, env_gl=None):
    (tmp_path / 'gl_probe.py').write_text(PROBE)
    env = {k: v for k, v in os.environ.items() if k != 'MUJOCO_GL'}
    if env_gl is not None:
        env['MUJOCO_GL'] = env_gl
    env['PYTHONPATH'] = os.pathsep.join([str(tmp_path), env.get('PYTHONPATH', '')])
    code = ('import sys\nfrom ifc_spg import entry\n'
            "entry.importlib.import_module('ifc_spg.cli').main = "
            "entry.importlib.import_module('gl_probe').main\n" + call)
    out = subprocess.run([sys.executable, '-c', code], env=env, capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize('name', ['spg_node', 'sim_bridge', 'task_publisher'])
def test_nodes_import_mujoco_without_glfw(tmp_path, name):
    res = _probe(tmp_path, f"entry._run('{name}', 'gl_probe:main')")
    assert res == {'glfw': False, 'gl': 'disable'}


@pytest.mark.parametrize('verb, renders', [('bag', False), ('run', False), ('render', True),
                                           ('demo', True)])
def test_ifc_spg_verbs_keep_gl_only_where_they_render(tmp_path, verb, renders):
    res = _probe(tmp_path, f"sys.argv = ['ifc-spg', '{verb}']\nentry.ifc_spg()")
    assert (res['gl'] != 'disable') == renders
    if not renders:
        assert res['glfw'] is False


def test_a_mujoco_gl_the_user_set_is_kept(tmp_path):
    res = _probe(tmp_path, "entry._run('sim_bridge', 'gl_probe:main')", env_gl='egl')
    assert res['gl'] == 'egl' and res['glfw'] is False


EXIT_PROBE = """
import atexit, ctypes, os, sys
def main():
    atexit.register(lambda: open(os.environ['ATEXIT_FILE'], 'w').write('finalized'))
    print('python output, block-buffered into a file')
    ctypes.CDLL(None).printf(b'C stdio output\\\\n')  # rcutils' console logging is C stdio
    return 3
"""


@pytest.mark.parametrize('program', ['spg_node', 'sim_bridge', 'task_publisher', 'ifc_spg bag',
                                     'ifc_spg run'])
def test_node_programs_end_without_the_interpreters_finalization(tmp_path, program):
    """The node programs (and ``ifc-spg bag``) end by os._exit once ``main`` returned: no
    atexit handler or static destructor runs (Fast DDS' joined its threads there: 0.2-2.9 s
    per stop), yet what they printed, from Python or C, reaches a file; with their status.
    Other ``ifc-spg`` verbs (a sweep's Dask cluster, a plot) finalize as usual."""
    (tmp_path / 'exit_probe.py').write_text(EXIT_PROBE)
    env = {**os.environ, 'ATEXIT_FILE': str(tmp_path / 'atexit'),
           'PYTHONPATH': os.pathsep.join([str(tmp_path), os.environ.get('PYTHONPATH', '')])}
    name, _, verb = program.partition(' ')
    code = ('import sys\nfrom ifc_spg import entry\n'
            "entry.importlib.import_module('ifc_spg.cli').main = "
            "entry.importlib.import_module('exit_probe').main\n"
            "for m in ('ifc_spg.node.spg_node', 'sim_bridge.node', "
            "'ifc_spg.cli.task_publisher'):\n"
            "    entry.importlib.import_module(m).main = "
            "entry.importlib.import_module('exit_probe').main\n"
            f"sys.argv = ['{name}', '{verb}']\nsys.exit(entry.{name}())\n")
    out_path = tmp_path / 'out.txt'
    with open(out_path, 'w') as out:
        proc = subprocess.run([sys.executable, '-c', code], env=env, stdout=out,
                              stderr=subprocess.STDOUT, timeout=120)
    text = out_path.read_text()
    assert proc.returncode == 3, text
    assert 'python output' in text and 'C stdio output' in text, text
    quick = verb != 'run'
    assert (tmp_path / 'atexit').exists() != quick
