"""The package's import graph has no cycle: a concept depends on the ones below it only.

Every ``import`` of an ``ifc_spg`` module counts, at module level or inside a function (a
deferred import hides a cycle from the interpreter, not from a reader) — except those under
``if TYPE_CHECKING:``, which only type checkers run (annotations naming a higher layer's type).
"""

import ast
import functools
import importlib.util
import os
from pathlib import Path
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ('ifc_spg', 'sim_bridge')


def _module_name(path):
    parts = list(path.relative_to(ROOT).with_suffix('').parts)
    if parts[-1] == '__init__':
        parts.pop()
    return '.'.join(parts)


def _type_checking_only(tree):
    """The import nodes under ``if TYPE_CHECKING:`` (or ``typing.TYPE_CHECKING``)."""
    hidden = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and (
                (isinstance(node.test, ast.Name) and node.test.id == 'TYPE_CHECKING') or
                (isinstance(node.test, ast.Attribute) and node.test.attr == 'TYPE_CHECKING')):
            for stmt in node.body:
                hidden.update(id(n) for n in ast.walk(stmt))
    return hidden


def import_graph():
    """{module: set of ifc_spg/sim_bridge modules it imports} from the source files."""
    files = {_module_name(p): p for pkg in PACKAGES for p in (ROOT / pkg).rglob('*.py')}
    graph = {}
    for name, path in files.items():
        deps = set()
        is_pkg = path.name == '__init__.py'
        tree = ast.parse(path.read_text(), str(path))
        hidden = _type_checking_only(tree)
        for node in ast.walk(tree):
            if id(node) in hidden:
                continue
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ''
                if node.level:
                    pkg = name if is_pkg else name.rpartition('.')[0]
                    for _ in range(node.level - 1):
                        pkg = pkg.rpartition('.')[0]
                    base = f'{pkg}.{base}' if base else pkg
                targets = [base] + [f'{base}.{a.name}' for a in node.names]
            else:
                continue
            for t in targets:
                # the module itself, else its nearest package in the tree
                while t and t not in files:
                    t = t.rpartition('.')[0]
                if t and t != name and not name.startswith(t + '.'):
                    deps.add(t)
        graph[name] = deps
    return graph


def find_cycle(graph):
    """One cycle as a list of modules, or None (iterative DFS with colours)."""
    colour = dict.fromkeys(graph, 0)
    for root in sorted(graph):
        if colour[root]:
            continue
        stack = [(root, iter(sorted(graph[root])))]
        path = [root]
        colour[root] = 1
        while stack:
            node, it = stack[-1]
            nxt = next(it, None)
            if nxt is None:
                colour[node] = 2
                stack.pop()
                path.pop()
            elif colour.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            elif colour.get(nxt) == 0:
                colour[nxt] = 1
                stack.append((nxt, iter(sorted(graph[nxt]))))
                path.append(nxt)
    return None


def test_the_cycle_finder_finds_a_cycle():
    assert find_cycle({'a': {'b'}, 'b': {'c'}, 'c': {'a'}, 'd': set()}) == ['a', 'b', 'c', 'a']
    assert find_cycle({'a': {'b'}, 'b': set()}) is None


def test_the_graph_sees_deferred_and_from_imports():
    graph = import_graph()
    assert 'ifc_spg.spg' in graph['ifc_spg.node.core']  # from ifc_spg.spg import ...
    assert 'ifc_spg.model.registry' in graph['ifc_spg.model.robot_model']
    assert len(graph) > 60


def test_type_checking_imports_are_not_edges():
    tree = ast.parse('from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import a\n'
                     'import b\n')
    hidden = _type_checking_only(tree)
    names = [n.names[0].name for n in ast.walk(tree)
             if isinstance(n, ast.Import) and id(n) not in hidden]
    assert names == ['b']


@pytest.mark.parametrize('package', PACKAGES)
def test_no_import_cycle(package):
    graph = import_graph()
    cycle = find_cycle(graph)
    assert cycle is None, 'import cycle: ' + ' -> '.join(cycle)


# The simulator sits beside the library, not inside its layers: it may use the robot models,
# the ROS layer and the error types, nothing of the SPG (ARCHITECTURE.md, "Who may import whom").
SIM_BRIDGE_MAY_IMPORT = ('ifc_spg.errors', 'ifc_spg.model', 'ifc_spg.ros')


def test_sim_bridge_imports_only_models_ros_and_errors_of_ifc_spg():
    graph = import_graph()
    bad = sorted((mod, dep) for mod, deps in graph.items() if mod.startswith('sim_bridge')
                 for dep in deps if dep.split('.')[0] == 'ifc_spg' and dep != 'ifc_spg'
                 and not any(dep == a or dep.startswith(a + '.') for a in SIM_BRIDGE_MAY_IMPORT))
    assert not bad, f'sim_bridge imports library layers above the models: {bad}'


def imported_packages(path):
    """Top-level names of the packages a module imports (not under ``TYPE_CHECKING``)."""
    return {name.split('.')[0] for name in named_imports(path)}


# The robot models are data for the SPG (pinocchio); loading them into MuJoCo is the
# simulator's (sim_bridge/models.py, sim_bridge/urdf.py).
def test_the_models_import_neither_mujoco_nor_a_layer_above_them():
    bad = sorted(f'{p.relative_to(ROOT)}: {name}'
                 for p in (ROOT / 'ifc_spg' / 'model').rglob('*.py')
                 for name in imported_packages(p) if name in ('mujoco', 'sim_bridge'))
    assert not bad, f'ifc_spg/model imports the simulator: {bad}'
    graph = import_graph()
    above = sorted((mod, dep) for mod, deps in graph.items() if mod.startswith('ifc_spg.model')
                   for dep in deps if not dep.startswith('ifc_spg.model')
                   and dep not in ('ifc_spg', 'ifc_spg.errors'))
    assert not above, f'ifc_spg/model imports layers above it: {above}'


# offline/ runs without DDS: its bags are files. Recording and playing over DDS is live/'s.
# Allowed of ros/: the wire format and its helpers (messages, cdr, qos, stamps, ...), not the
# backend picker (``ifc_spg.ros`` itself) nor a transport.
DDS_TRANSPORT = ('ifc_spg.ros', 'ifc_spg.ros.dds', 'ifc_spg.ros.builtin_backend',
                 'ifc_spg.ros.rclpy_backend', 'ifc_spg.ros.msg')
DDS_PACKAGES = ('rclpy', 'cyclonedds')


@functools.cache
def _tree_modules():
    """The dotted names of every module of the packages (read once)."""
    return frozenset(_module_name(p) for pkg in PACKAGES for p in (ROOT / pkg).rglob('*.py'))


def named_imports(path):
    """Every module a source file names in an import (not under ``TYPE_CHECKING``):
    ``from a import b`` names ``a.b`` if that is a module of the tree, else ``a``."""
    files = _tree_modules()
    tree = ast.parse(path.read_text(), str(path))
    hidden = _type_checking_only(tree)
    names = set()
    for node in ast.walk(tree):
        if id(node) in hidden:
            continue
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            for a in node.names:
                sub = f'{node.module}.{a.name}'
                names.add(sub if sub in files else node.module)
    return names


def test_named_imports_tell_a_submodule_from_a_name_of_the_package(tmp_path):
    path = tmp_path / 'm.py'
    path.write_text('from ifc_spg.ros import messages\nfrom ifc_spg.ros import QoSProfile\n'
                    'from ifc_spg import ros\n')
    assert named_imports(path) == {'ifc_spg.ros.messages', 'ifc_spg.ros'}


def test_offline_imports_no_dds_transport():
    bad = sorted(f'{p.relative_to(ROOT)}: {name}'
                 for p in (ROOT / 'ifc_spg' / 'offline').rglob('*.py')
                 for name in named_imports(p)
                 if name in DDS_TRANSPORT or name.split('.')[0] in DDS_PACKAGES)
    assert not bad, f'offline/ imports the DDS transport (live record/play is live/): {bad}'


def _fresh_interpreter(code, backend=None):
    """Run ``code`` in a new interpreter (nothing imported yet) on this tree; its stdout."""
    env = {k: v for k, v in os.environ.items() if k != 'IFC_SPG_ROS_BACKEND'}
    env['PYTHONPATH'] = os.pathsep.join(filter(None, (str(ROOT), env.get('PYTHONPATH'))))
    if backend is not None:
        env['IFC_SPG_ROS_BACKEND'] = backend
    done = subprocess.run([sys.executable, '-c', code], env=env, cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return done.stdout


LOADED = ("import sys; print(sorted(k for k in sys.modules if k.split('.')[0] in {pkgs} "
          "or k in {transport}))")


def test_offline_and_the_wire_format_load_no_dds_library():
    """ifc_spg.ros picks its backend on first use of a backend name, not when a submodule
    (the wire format, stamps) is imported: MCAP files alone load neither rclpy nor Cyclone DDS."""
    modules = [_module_name(p) for p in sorted((ROOT / 'ifc_spg' / 'offline').rglob('*.py'))]
    modules += ['ifc_spg.ros.stamps', 'ifc_spg.ros.cdr', 'ifc_spg.ros.messages']
    code = ''.join(f'import {m}; ' for m in modules) + LOADED.format(
        pkgs=set(DDS_PACKAGES), transport=set(DDS_TRANSPORT) - {'ifc_spg.ros'})
    assert _fresh_interpreter(code).strip() == '[]'


@pytest.mark.parametrize('backend', ['rclpy', 'cyclonedds'])
def test_the_backend_is_picked_on_first_use_as_before(backend):
    if backend == 'rclpy' and importlib.util.find_spec('rclpy') is None:
        pytest.skip('rclpy is not installed')
    module = {'rclpy': 'rclpy_backend', 'cyclonedds': 'builtin_backend'}[backend]
    out = _fresh_interpreter(
        'import sys; from ifc_spg import ros; '
        "print('rclpy' in sys.modules); "
        f'from ifc_spg.ros import Node, {module}; '
        f'print(ros.BACKEND, ros.Node is Node is {module}.Node, '
        f"ros.spin_until is {module}.spin_until, 'rclpy' in sys.modules); print(ros.describe())",
        backend=backend)
    assert out.split('\n')[:2] == ['False', f'{backend} True True {backend == "rclpy"}']
    assert out.split('\n')[2].startswith(f'ROS 2 backend: {backend} on ')


def test_a_bad_backend_choice_fails_on_first_use_with_the_same_message():
    out = _fresh_interpreter(
        'import ifc_spg.ros.stamps\nfrom ifc_spg import ros\n'
        'try:\n    ros.BACKEND\nexcept ImportError as exc:\n    print(exc)', backend='bogus')
    assert out.strip() == "IFC_SPG_ROS_BACKEND='bogus' is not one of auto, rclpy, cyclonedds"


# Command lines live in ifc_spg/cli/, one module per verb (and per executable); the library
# builds no parser.
PARSERS_MAY_LIVE_IN = ('ifc_spg.cli',)


def argparse_parsers(tree):
    """Line numbers of the ``argparse.ArgumentParser(...)`` calls in a module's syntax tree,
    however argparse or the class was imported (``import argparse as ap``, ``from argparse
    import ArgumentParser as P``)."""
    modules, classes = set(), set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            modules.update(a.asname or a.name for a in node.names if a.name == 'argparse')
        elif isinstance(node, ast.ImportFrom) and node.module == 'argparse':
            classes.update(a.asname or a.name for a in node.names if a.name == 'ArgumentParser')
    lines = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        f = node.func
        if (isinstance(f, ast.Attribute) and f.attr == 'ArgumentParser' and
                isinstance(f.value, ast.Name) and f.value.id in modules) or \
                (isinstance(f, ast.Name) and f.id in classes):
            lines.append(node.lineno)
    return sorted(lines)


def test_the_parser_finder_sees_every_spelling():
    src = ('import argparse\nimport argparse as ap\nfrom argparse import ArgumentParser as P\n'
           'argparse.ArgumentParser()\nap.ArgumentParser(prog="x")\nP()\n'
           '# argparse.ArgumentParser()\ns = "argparse.ArgumentParser()"\nArgumentParser()\n')
    assert argparse_parsers(ast.parse(src)) == [4, 5, 6]


def test_only_the_command_lines_build_argparse_parsers():
    bad = []
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob('*.py')):
            name = _module_name(path)
            if any(name == a or name.startswith(a + '.') for a in PARSERS_MAY_LIVE_IN):
                continue
            bad += [f'{path.relative_to(ROOT)}:{line}'
                    for line in argparse_parsers(ast.parse(path.read_text(), str(path)))]
    assert not bad, f'argparse parsers outside ifc_spg/cli/ (move the command line there): {bad}'


def test_nothing_in_the_library_imports_the_command_lines():
    graph = import_graph()
    bad = sorted((mod, dep) for mod, deps in graph.items() if not mod.startswith('ifc_spg.cli')
                 for dep in deps if dep == 'ifc_spg.cli' or dep.startswith('ifc_spg.cli.'))
    assert not bad, f'the command lines are the top layer; imported by: {bad}'
