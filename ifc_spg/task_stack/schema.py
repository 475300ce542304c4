"""The JSON Schema of the task-stack format, generated from the parser's tables.

The shipped file ``ifc_spg/schema/task_stack.schema.json`` is this schema (a test keeps
them equal); regenerate it with ``python -m ifc_spg.task_stack.schema > FILE``. Editors
use it to validate and complete stacks; the parser (:mod:`ifc_spg.task_stack.spec`) is
stricter (orthonormal columns, robot-dependent checks) and gives the better messages.
"""

import json
import os
import sys
from typing import Any

from ifc_spg.geometry.collision import OBSTACLE_SHAPES
from ifc_spg.task_stack.collision import MAX_OBSTACLES, OBSTACLE_FIELDS
from ifc_spg.task_stack.spec import (
    BOUND_FIELDS,
    MAX_DIM,
    MAX_POWER_BUDGET,
    MAX_TASKS,
    REQUIRED,
    SUBSPACE_FIELDS,
    TASK_FIELDS,
    TASK_TYPES,
    TOPIC_PATTERN,
    TRAJECTORIES,
    TRAJECTORY_ALIASES,
    VERSION,
)
from ifc_spg.tasks.subspace import AXES, SUBSPACE_FRAMES, WRENCH_AXES

__all__ = ['SCHEMA_PATH', 'load_schema', 'schema']

SCHEMA_PATH = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                           'schema', 'task_stack.schema.json')

_NUM = {'type': 'number'}
_INIT = {'const': 'init'}


def _vector(init=False, open_=False):
    entry = [_NUM] + ([_INIT] if init else []) + ([{'type': 'null'}] if open_ else [])
    e = entry[0] if len(entry) == 1 else {'anyOf': entry}
    forms = [_NUM, {'type': 'array', 'items': e, 'minItems': 1, 'maxItems': MAX_DIM},
             {'type': 'object', 'additionalProperties': e, 'minProperties': 1,
              'maxProperties': MAX_DIM}]
    if init:
        forms.append(_INIT)
    return {'anyOf': forms}


def _param(kind):
    if kind == 'vector':
        return {'$ref': '#/$defs/vector'}
    if kind in ('anchor', 'anchor_to'):
        return {'$ref': '#/$defs/anchor'}
    if kind == 'anchor2':  # the parser also takes one number for both components
        return {'anyOf': [_INIT, _NUM, {'type': 'array', 'items': {'anyOf': [_NUM, _INIT]},
                                  'minItems': 2, 'maxItems': 2}]}
    if kind == 'offsets':
        return {'type': 'array', 'items': {'$ref': '#/$defs/vector'}, 'minItems': 2,
                'maxItems': 2}
    if kind == 'plane':
        return {'anyOf': [{'type': 'string'},
                          {'type': 'array', 'items': {'type': ['string', 'integer']},
                           'minItems': 2, 'maxItems': 2}]}
    if kind == 'positive':
        return {'type': 'number', 'exclusiveMinimum': 0}
    if kind == 'nonnegative':
        return {'type': 'number', 'minimum': 0}
    if kind == 'fraction':
        return {'type': 'number', 'exclusiveMinimum': 0, 'exclusiveMaximum': 1}
    return dict(_NUM)


def _trajectory(kind):
    names = [kind] + [a for a, k in TRAJECTORY_ALIASES.items() if k == kind]
    props = {'trajectory': {'enum': names}}
    props.update({p: _param(k) for p, (k, _) in TRAJECTORIES[kind].items()})
    required = ['trajectory'] + [p for p, (_, d) in TRAJECTORIES[kind].items() if d is REQUIRED]
    return {'type': 'object', 'properties': props, 'required': required,
            'additionalProperties': False, 'title': f'{kind} trajectory'}


def _collision_task(common):
    names = {'anyOf': [{'type': 'string'}, {'type': 'array', 'items': {'type': 'string'},
                                             'minItems': 1}]}
    group = {'anyOf': [{'const': 'self'}, {
        'type': 'object', 'additionalProperties': False, 'required': ['links', 'obstacles'],
        'properties': {'name': {'type': 'string', 'minLength': 1}, 'links': names,
                       'obstacles': names}}]}
    props = dict(common)
    props['pairs'] = {'anyOf': [group, {'type': 'array', 'items': group, 'minItems': 1}],
                      'description': "'self' (the model's self-collision pairs) and/or "
                                     '{links: [...] or all, obstacles: [...]}.'}
    props['margin'] = {'type': 'number', 'minimum': 0,
                       'description': 'd_s [m]: never closer (default 0.01).'}
    props['influence'] = {'type': 'number', 'exclusiveMinimum': 0,
                          'description': 'd_i [m] > margin: rows for pairs closer than this '
                                         '(default 0.1).'}
    props['gain'] = {'type': 'number', 'exclusiveMinimum': 0,
                     'description': 'xi [m/s]: approach speed allowed at d_i (default 0.5).'}
    props['max_rows'] = {'type': 'integer', 'minimum': 1, 'maximum': 1000,
                         'description': 'Rows of the level: the closest pairs within d_i '
                                        '(default 24).'}
    extra = set(props) ^ set(TASK_FIELDS['collision_avoidance'])
    if extra:
        raise RuntimeError(f'schema and parser disagree on collision_avoidance: {extra}')
    return {'type': 'object', 'properties': props, 'required': ['type', 'pairs'],
            'additionalProperties': False, 'title': 'collision_avoidance task',
            'description': 'Velocity damper d_dot >= -gain (d - margin) / (influence - '
                           'margin) on every listed pair closer than influence (an '
                           'inequality level).'}


def _obstacle():
    num3 = {'type': 'array', 'items': _NUM, 'minItems': 3, 'maxItems': 3}
    size = {'type': 'number', 'exclusiveMinimum': 0}
    props = {'name': {'type': 'string', 'minLength': 1},
             'shape': {'enum': list(OBSTACLE_SHAPES)},
             'size': {'type': 'array', 'items': size, 'minItems': 3, 'maxItems': 3,
                      'description': 'box: full edge lengths [m].'},
             'radius': size, 'length': size,
             'frame': {'type': 'string', 'description': 'base (default) or a chain id.'},
             'position': num3, 'rpy': num3, 'description': {'type': ['string', 'null']}}
    if set(props) != set(OBSTACLE_FIELDS):
        raise RuntimeError('schema and parser disagree on obstacles')
    return {'type': 'object', 'properties': props, 'required': ['name', 'shape'],
            'additionalProperties': False}


def _task(ttype):
    common = {
        'name': {'type': 'string', 'minLength': 1, 'description': 'Task name (unique).'},
        'type': {'const': ttype},
        'description': {'type': ['string', 'null']},
    }
    if ttype == 'collision_avoidance':
        return _collision_task(common)
    if ttype == 'constrained_manipulation':
        common['frame'] = {'type': 'string', 'description': 'Chain id grasping the mechanism.'}
        return {'type': 'object', 'properties': common, 'required': ['type', 'frame'],
                'additionalProperties': True,
                'description': 'Constrained manipulation (thesis Ch. 5, Table 5.1); further '
                               'fields (kappa, force, estimator, orientation, ...) are read by '
                               'ifc_spg.constrained.'}
    props = dict(common)
    for b in BOUND_FIELDS:
        props[b] = {'$ref': '#/$defs/bound_equal' if b == 'equal' else '#/$defs/bound_open'}
    props['gain'] = {'$ref': '#/$defs/vector', 'description': 'Convergence gain Lambda [1/s].'}
    props['feedforward'] = {'anyOf': [{'enum': ['trajectory', 'none', 'zero', None]},
                                      {'$ref': '#/$defs/vector'}],
                            'description': "'trajectory' (bounds' rates, default), none, or "
                                           'rates per component.'}
    props['velocity_gain'] = dict(_NUM, description='k_d: adds k_d times the measured task '
                                                    'rate to the feed-forward (Table 4.5).')
    props['compensate_velocity'] = {'type': 'boolean',
                                    'description': 'Velocity compensation gamma (Table 5.1).'}
    if ttype in ('wrench', 'joint_torque'):
        props['include_damping'] = {
            'type': 'boolean', 'description': 'The static value includes the IFC damping of '
            'the measured motion, -D qdot (default false, as in the thesis).'}
    required = ['type']
    if ttype in ('cartesian_pose', 'wrench'):
        props['frame'] = {'type': 'string', 'description': 'Chain id, e.g. tool.'}
        props['subspace'] = {'anyOf': [{'type': 'null'}, {
            '$ref': '#/$defs/subspace_pose' if ttype == 'cartesian_pose'
            else '#/$defs/subspace_wrench'}], 'description': 'Default (null): all six axes.'}
        required.append('frame')
    else:
        props['joints'] = {'anyOf': [{'type': 'string'}, {'type': 'null'},
                                     {'type': 'array', 'items': {'type': 'string'},
                                      'minItems': 1, 'uniqueItems': True}]}
    if ttype == 'cartesian_pose':
        props['orientation'] = {'anyOf': [_INIT, {
            'type': 'array', 'minItems': 3, 'maxItems': 3,
            'items': {'type': 'array', 'items': _NUM, 'minItems': 3, 'maxItems': 3}}]}
        props['relative'] = {'type': 'boolean'}
    extra = set(props) - set(TASK_FIELDS[ttype])
    if extra:
        raise RuntimeError(f'schema and parser disagree on {ttype}: {extra}')
    return {'type': 'object', 'properties': props, 'required': required,
            'additionalProperties': False,
            'anyOf': [{'required': ['equal']}, {'required': ['lower']},
                      {'required': ['upper']}],
            'not': {'required': ['equal', 'lower']}, 'title': f'{ttype} task'}


def _subspace(axes):
    alias = list(AXES) + list(WRENCH_AXES)
    ax = {'anyOf': [{'type': 'string'},
                    {'type': 'array', 'items': {'enum': alias}, 'minItems': 1, 'maxItems': 6,
                     'uniqueItems': True}]}
    col = {'type': 'array', 'items': _NUM, 'minItems': 6, 'maxItems': 6}
    return {'anyOf': [ax, {
        'type': 'object', 'additionalProperties': False,
        'properties': {'axes': ax, 'columns': {'type': 'array', 'items': col, 'minItems': 1,
                                               'maxItems': 6},
                       'frame': {'enum': list(SUBSPACE_FRAMES)}},
        'oneOf': [{'required': ['axes']}, {'required': ['columns']}]}],
        'description': f"Axis names ({' '.join(axes)}) or explicit orthonormal columns (6 "
                       'numbers each); frame base | ee | ee_orientation.'}


def schema() -> dict[str, Any]:
    """Return the JSON Schema (draft 2020-12) of task-stack version 1 as a dict."""
    if set(SUBSPACE_FIELDS) != {'axes', 'columns', 'frame'}:
        raise RuntimeError('subspace fields changed; update the schema')
    trajectories = [_trajectory(k) for k in TRAJECTORIES]
    bound = {'anyOf': [_NUM, _INIT, {'$ref': '#/$defs/trajectory'}]}
    stream = {'type': 'object', 'additionalProperties': False, 'required': ['stream'],
              'title': 'streamed target',
              'description': 'Follow the latest message on a topic (null: spg/reference/'
                             '<task name>): geometry_msgs/PoseStamped (cartesian_pose), '
                             'sensor_msgs/JointState (joint_position), geometry_msgs/'
                             'WrenchStamped (wrench); held after stale_after [s].',
              'properties': {'stream': {'type': ['string', 'null'],
                                        'pattern': TOPIC_PATTERN},
                             'stale_after': {'type': 'number', 'exclusiveMinimum': 0,
                                             'maximum': 1e6}}}
    return {
        '$schema': 'https://json-schema.org/draft/2020-12/schema',
        '$id': 'https://github.com/ifc-spg/ifc_spg/schema/task_stack.schema.json',
        'title': 'ifc_spg task stack',
        'description': 'Hierarchical force and positioning tasks for robots under indirect '
                       'force control; task order = priority (first is highest).',
        'type': 'object',
        'additionalProperties': False,
        'required': ['version', 'tasks'],
        'properties': {
            'version': {'const': VERSION},
            'name': {'type': 'string', 'minLength': 1},
            'robot': {'type': ['string', 'null'],
                      'description': 'Robot model the stack is written for (a hint).'},
            'description': {'type': ['string', 'null']},
            'power_budget': {'type': ['number', 'null'], 'minimum': 0,
                             'maximum': MAX_POWER_BUDGET,
                             'description': 'Refill rate of the PSPM energy tanks in [W] the '
                             'stack needs to do work on its environment (sliding a tool, '
                             'lifting a drawer); at most the node parameter pspm.max_power. '
                             'Absent or 0: strictly passive.'},
            'obstacles': {'type': ['array', 'null'], 'items': _obstacle(),
                          'maxItems': MAX_OBSTACLES,
                          'description': 'Known obstacles (box, sphere, capsule, cylinder, '
                                         'plane) for collision_avoidance tasks.'},
            'tasks': {'type': 'array', 'minItems': 1, 'maxItems': MAX_TASKS,
                      'items': {'$ref': '#/$defs/task'}},
        },
        '$defs': {
            'vector': _vector(),
            'anchor': _vector(init=True),
            'trajectory': {'anyOf': trajectories},
            'bound_equal': {'anyOf': [bound, {'$ref': '#/$defs/constant_equal'}, stream]},
            'bound_open': {'anyOf': [bound, {'$ref': '#/$defs/constant_open'}]},
            'constant_equal': _vector(init=True),
            'constant_open': _vector(init=True, open_=True),
            'subspace_pose': _subspace(AXES),
            'subspace_wrench': _subspace(WRENCH_AXES),
            'task': {'type': 'object', 'required': ['type'],
                     'properties': {'type': {'enum': list(TASK_TYPES)}},
                     'oneOf': [_task(t) for t in TASK_TYPES]},
        },
    }


def load_schema() -> dict[str, Any]:
    """Return the shipped schema file as a dict."""
    with open(SCHEMA_PATH, encoding='utf-8') as f:
        return json.load(f)


def dumps() -> str:
    """The schema as the text of the shipped file."""
    return json.dumps(schema(), indent=2) + '\n'


if __name__ == '__main__':
    sys.stdout.write(dumps())
