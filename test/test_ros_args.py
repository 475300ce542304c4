"""Table-driven tests of the ``--ros-args`` grammar (parse_ros_args) and name resolution."""

import textwrap

import pytest

from ifc_spg.errors import ParameterError
from ifc_spg.ros.names import expand_topic_name, remap_name
from ifc_spg.ros.ros_args import Remap, parse_ros_args, remove_ros_args

PARAMS_YAML = textwrap.dedent("""\
    /**:
      ros__parameters:
        rate: 100.0
        count: 5
        gains:
          kp: 1.5
          inner:
            ki: [0.1, 0.2]
        frame: base
    talker:
      ros__parameters:
        rate: 250.0
        joints: [a1, a2]
    /robot/talker:
      ros__parameters:
        count: 9
    /other:
      listener:
        ros__parameters:
          verbose: true
    """)


@pytest.fixture
def params_file(tmp_path):
    path = tmp_path / 'params.yaml'
    path.write_text(PARAMS_YAML)
    return str(path)


# (argv, node fqn, expected overrides)
OVERRIDE_CASES = [
    (['--ros-args', '-p', 'rate:=500'], '/talker', {'rate': 500}),
    (['--ros-args', '-p', 'rate:=500.0'], '/talker', {'rate': 500.0}),
    (['--ros-args', '-p', 'on:=true', '-p', 's:=hello', '-p', 'l:=[1, 2]'], '/n',
     {'on': True, 's': 'hello', 'l': [1, 2]}),
    (['--ros-args', '-p', "s:='42'"], '/n', {'s': '42'}),
    (['--ros-args', '-p', 'a.b.c:=1.5e-3'], '/n', {'a.b.c': 1.5e-3}),
    (['--ros-args', '-p', 'talker:rate:=7.0', '-p', 'listener:rate:=8.0'], '/talker',
     {'rate': 7.0}),
    (['--ros-args', '-p', 'rate:=1.0', '-p', 'rate:=2.0'], '/n', {'rate': 2.0}),
    # params file: wildcard, node name, nested keys flattened with '.'
    (['--ros-args', '--params-file', '{file}'], '/listener',
     {'rate': 100.0, 'count': 5, 'gains.kp': 1.5, 'gains.inner.ki': [0.1, 0.2], 'frame': 'base'}),
    (['--ros-args', '--params-file', '{file}'], '/talker',
     {'rate': 250.0, 'count': 5, 'gains.kp': 1.5, 'gains.inner.ki': [0.1, 0.2], 'frame': 'base',
      'joints': ['a1', 'a2']}),
    (['--ros-args', '--params-file', '{file}'], '/robot/talker',
     {'rate': 100.0, 'count': 9, 'gains.kp': 1.5, 'gains.inner.ki': [0.1, 0.2], 'frame': 'base'}),
    (['--ros-args', '--params-file', '{file}'], '/other/listener',
     {'rate': 100.0, 'count': 5, 'gains.kp': 1.5, 'gains.inner.ki': [0.1, 0.2], 'frame': 'base',
      'verbose': True}),
    # precedence: -p after the file beats the file
    (['--ros-args', '--params-file', '{file}', '-p', 'count:=42', '-p', 'gains.kp:=3.0'],
     '/listener', {'rate': 100.0, 'count': 42, 'gains.kp': 3.0, 'gains.inner.ki': [0.1, 0.2],
                   'frame': 'base'}),
    # rcl merges in command-line order: a later file beats an earlier -p of the same section
    (['--ros-args', '-p', 'count:=42', '--params-file', '{file}'], '/listener',
     {'count': 5, 'rate': 100.0, 'gains.kp': 1.5, 'gains.inner.ki': [0.1, 0.2],
      'frame': 'base'}),
    # several --ros-args sections
    (['prog', '--ros-args', '-p', 'a:=1', '--', 'x', '--ros-args', '-p', 'b:=2'], '/n',
     {'a': 1, 'b': 2}),
]


@pytest.mark.parametrize(('argv', 'fqn', 'expected'), OVERRIDE_CASES)
def test_parameter_overrides(argv, fqn, expected, params_file):
    argv = [a.replace('{file}', params_file) for a in argv]
    overrides = parse_ros_args(argv).parameter_overrides(fqn)
    assert overrides == expected
    for name, value in expected.items():
        assert type(overrides[name]) is type(value), name


# (argv, user args, remaps, node name for 'talker', namespace, log levels)
STRUCTURE_CASES = [
    ([], (), (), 'talker', '/', {}),
    (['prog', 'a', '--ros-args', '-r', '__ns:=/robot', '-r', '__node:=t2'], ('prog', 'a'),
     (Remap(None, '__ns', '/robot'), Remap(None, '__node', 't2')), 't2', '/robot', {}),
    (['--ros-args', '-r', 'talker:__node:=t3', '-r', 'other:__node:=t4'], (),
     (Remap('talker', '__node', 't3'), Remap('other', '__node', 't4')), 't3', '/', {}),
    (['--ros-args', '-r', '__name:=t5', '-r', '__node:=t6'], (),
     (Remap(None, '__name', 't5'), Remap(None, '__node', 't6')), 't5', '/', {}),
    (['--ros-args', '-r', 'joint_states:=/robot/js', '--', 'tail'], ('tail',),
     (Remap(None, 'joint_states', '/robot/js'),), 'talker', '/', {}),
    (['--ros-args', '--log-level', 'DEBUG', '--log-level', 'talker:=warn'], (), (), 'talker',
     '/', {'': 'debug', 'talker': 'warn'}),
    (['--ros-args', '--disable-rosout-logs', '-e', '/enc'], (), (), 'talker', '/', {}),
]


@pytest.mark.parametrize(('argv', 'user', 'remaps', 'node', 'ns', 'levels'), STRUCTURE_CASES)
def test_structure(argv, user, remaps, node, ns, levels):
    args = parse_ros_args(argv)
    assert args.user_args == user
    assert args.remaps == remaps
    assert args.node_name('talker') == node
    assert args.namespace('/') == ns
    assert args.log_levels == levels
    assert remove_ros_args(argv) == list(user)


# (argv, regex of the ParameterError message)
ERROR_CASES = [
    (['--ros-args', '-p'], r"'-p' at the end .* needs a value, e.g. -p rate:=500.0"),
    (['--ros-args', '-p', 'rate=5'], r"malformed '-p rate=5': expected -p name:=value"),
    (['--ros-args', '-p', '1rate:=5'], r"invalid parameter name '1rate'"),
    (['--ros-args', '-p', 'x:=[1, a]'], r'one type of bool, int, float or str, got int, str'),
    (['--ros-args', '-p', 'x:={a: 1}'], r'unsupported value'),
    (['--ros-args', '-p', 'x:=[1'], r'cannot parse the value .* as YAML'),
    (['--ros-args', '-r', 'a'], r"malformed '-r a': expected -r name:=value"),
    (['--ros-args', '-r', '__ns:=robot'], r'namespace must be absolute, e.g. __ns:=/robot'),
    (['--ros-args', '-r', '__ns:=/1robot'], r"token '1robot'"),
    (['--ros-args', '-r', '__node:=my-node'], r"invalid node name 'my-node'"),
    (['--ros-args', '-r', '__nod:=x'], r"unknown special remap '__nod'.*valid: __ns"),
    (['--ros-args', '--param-file', 'x.yaml'],
     r"unknown ROS argument '--param-file'; did you mean '--params-file'\?"),
    (['--ros-args', '--log-level', 'verbose'], r"invalid log level 'verbose'.*valid: debug"),
    (['--ros-args', '--params-file', '/nonexistent/p.yaml'], r'cannot read params file'),
    (['--ros-args', '--params-file', '{bad_yaml}'], r'is not valid YAML'),
    (['--ros-args', '--params-file', '{no_section}'], r"not inside 'ros__parameters'"),
    (['--ros-args', '--params-file', '{not_mapping}'], r'expected a mapping of node names'),
]


@pytest.mark.parametrize(('argv', 'pattern'), ERROR_CASES)
def test_malformed_arguments_raise_clear_errors(argv, pattern, tmp_path):
    files = {
        'bad_yaml': 'a: [1, 2\n',
        'no_section': 'talker:\n  rate: 5\n',
        'not_mapping': '- 1\n- 2\n',
    }
    for key, text in files.items():
        (tmp_path / f'{key}.yaml').write_text(text)
    for key in files:
        argv = [a.replace('{' + key + '}', str(tmp_path / f'{key}.yaml')) for a in argv]
    with pytest.raises(ParameterError, match=pattern):
        parse_ros_args(argv)


# (name, node, namespace, expanded)
EXPAND_CASES = [
    ('joint_states', 'spg', '/', '/joint_states'),
    ('joint_states', 'spg', '/robot', '/robot/joint_states'),
    ('/abs/topic', 'spg', '/robot', '/abs/topic'),
    ('~/status', 'spg', '/robot', '/robot/spg/status'),
    ('~', 'spg', '/', '/spg'),
    ('spg/status', 'spg', '/a/b', '/a/b/spg/status'),
    ('{node}/x', 'spg', '/r', '/r/spg/x'),
]


@pytest.mark.parametrize(('name', 'node', 'ns', 'expanded'), EXPAND_CASES)
def test_expand_topic_name(name, node, ns, expanded):
    assert expand_topic_name(name, node, ns) == expanded


@pytest.mark.parametrize('bad', ['', 'a//b', 'a/', '1abc', 'a b', 'a/-b'])
def test_bad_topic_names(bad):
    with pytest.raises(ParameterError, match='invalid topic name'):
        expand_topic_name(bad, 'node', '/')


def test_remap_first_match_wins_and_node_specific_rules():
    rules = parse_ros_args(['--ros-args', '-r', 'other:js:=/nope', '-r', 'js:=/robot/js',
                            '-r', 'js:=/later', '-r', '/abs:=rel']).remaps
    assert remap_name('/ns/js', rules, 'talker', '/ns') == '/robot/js'
    assert remap_name('/js', rules, 'talker', '/') == '/robot/js'
    assert remap_name('/abs', rules, 'talker', '/ns') == '/ns/rel'
    assert remap_name('/untouched', rules, 'talker', '/') == '/untouched'
