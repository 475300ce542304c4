"""Fuzz: >= 5000 generated and mutated documents never raise anything but TaskStackError.

Seeded: documents start from the shipped stacks and valid random stacks, then get
structural mutations (drop/replace/retype/rename fields, wrong sizes, odd values) or text
mutations (byte edits, truncation, YAML aliases and tags). Each document is parsed and
validated against its robot within a time bound. Accepted documents must also satisfy the
shipped JSON Schema (the parser is stricter, never looser).
"""

import copy
import glob
import json
import os
import time

import jsonschema
import numpy as np
import yaml

from ifc_spg.model import RobotModel
from ifc_spg.task_stack import TaskStack, TaskStackError, schema

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _load(path):
    with open(path, encoding='utf-8') as f:
        return yaml.safe_load(f)


SEEDS = [_load(f) for f in sorted(glob.glob(os.path.join(ROOT, 'config', 'tasks', '*.yaml')))]
N_DOCS = 5000
MAX_SECONDS_PER_DOC = 1.0  # CPU seconds; worst seen 0.061 s at load 8 (wall time was 1.7 s there)
DUMPER = getattr(yaml, 'CSafeDumper', yaml.SafeDumper)

ODD = [None, True, False, 0, -1, 1e308, -1e-300, 3.5, '', 'init', 'tool', 'x', 'A1', 'fz',
       'nan', '.inf', [], {}, [0], [1, 2, 3], [[0, 0, 1, 0, 0, 0]], {'trajectory': 'circle'},
       {'trajectory': 'sine', 'amplitude': 1, 'frequency': 1}, 'y z', [None], ['init', 1],
       {'trajectory': 'ramp', 'to': {'x': 1}, 'duration': 0}, {'axes': ['x'], 'frame': 'ee'},
       {'columns': [[1, 0, 0, 0, 0, 0], [1, 0, 0, 0, 0, 0]]}, 'a' * 300, 10 ** 30, -0.0]
KEYS = ['version', 'name', 'tasks', 'type', 'frame', 'joints', 'subspace', 'equal', 'lower',
        'upper', 'gain', 'feedforward', 'velocity_gain', 'compensate_velocity', 'orientation',
        'relative', 'trajectory', 'plane', 'radius', 'frequency', 'center', 'start',
        'amplitude', 'phase', 'offset', 'offsets', 'period', 'duty', 'transition', 'from',
        'to', 'by', 'duration', 'delay', 'axes', 'columns', 'kappa', 'estimator', 'gian']
TRAJ = [
    {'trajectory': 'circle', 'plane': 'xy', 'radius': 0.05, 'frequency': 0.2},
    {'trajectory': 'sine', 'amplitude': {'x': 0.1}, 'frequency': 0.3, 'phase': 1.0},
    {'trajectory': 'square', 'offsets': [0, {'y': 0.1}], 'period': 2.0, 'transition': 0.2},
    {'trajectory': 'min_jerk', 'by': {'z': -0.05}, 'duration': 1.0},
    {'trajectory': 'ramp', 'from': 'init', 'to': {'x': 0.4}, 'duration': 2.0, 'delay': 0.5},
]


def random_valid(rng):
    tasks = []
    for i in range(rng.integers(1, 5)):
        kind = rng.choice(['cartesian_pose', 'wrench', 'joint_position', 'joint_torque'])
        t = {'name': f't{i}', 'type': str(kind)}
        if kind == 'cartesian_pose':
            t.update(frame='tool', subspace=['x', 'y', 'z'],
                     equal=copy.deepcopy(TRAJ[rng.integers(len(TRAJ))]))
        elif kind == 'wrench':
            t.update(frame='tool', subspace={'axes': ['fz', 'fx'], 'frame': 'ee'},
                     lower=[-5.0, -1.0], upper=[5.0, None])
        else:
            t.update(joints=['A1', 'A3'], equal=['init', 0.1], gain={'A1': 2.0})
        tasks.append(t)
    return {'version': 1, 'robot': 'lbr4', 'tasks': tasks}


def nodes(x, path=()):
    yield path, x
    if isinstance(x, dict):
        for k, v in x.items():
            yield from nodes(v, path + (k,))
    elif isinstance(x, list):
        for i, v in enumerate(x):
            yield from nodes(v, path + (i,))


def mutate(doc, rng):
    doc = copy.deepcopy(doc)
    for _ in range(rng.integers(1, 4)):
        all_nodes = list(nodes(doc))
        path, _ = all_nodes[rng.integers(len(all_nodes))]
        if not path:
            continue
        parent = doc
        for p in path[:-1]:
            parent = parent[p]
        key = path[-1]
        op = rng.integers(6)
        if op == 0:
            del parent[key]
        elif op == 1:
            parent[key] = copy.deepcopy(ODD[rng.integers(len(ODD))])
        elif op == 2 and isinstance(parent, dict):
            parent[KEYS[rng.integers(len(KEYS))]] = copy.deepcopy(ODD[rng.integers(len(ODD))])
        elif op == 3 and isinstance(parent[key], list):
            parent[key] = parent[key] + parent[key][:1] if rng.random() < 0.5 \
                else parent[key][1:]
        elif op == 4 and isinstance(parent[key], (int, float)) and \
                not isinstance(parent[key], bool):
            parent[key] = float(parent[key]) * float(rng.choice([-1, 0, 1e6, 1e-9, 3]))
        elif op == 5 and isinstance(parent[key], str):
            s = parent[key]
            i = rng.integers(len(s) + 1)
            parent[key] = s[:i] + str(rng.choice(['9', '', 'x', '_'])) + s[i + 1:]
    return doc


TEXT_SNIPPETS = ['&a ', '*a', '!!python/object:os.system ', ': ', '- ', '{', '}', '[', ']',
                 '\t', '"', "'", '\n  ', '#', '\x00', '\ufeff', '<<: *a\n', '!!binary ',
                 '.nan', '1e999', '~', '|\n  ', '---\n', '...\n', '%YAML 1.1\n']


def mutate_text(text, rng):
    for _ in range(rng.integers(1, 4)):
        i = int(rng.integers(len(text) + 1))
        op = rng.integers(3)
        if op == 0:
            text = text[:i] + TEXT_SNIPPETS[rng.integers(len(TEXT_SNIPPETS))] + text[i:]
        elif op == 1:
            text = text[:i] + text[i + int(rng.integers(1, 20)):]
        else:
            text = text[:i]
    return text


def test_fuzz_only_task_stack_errors():
    rng = np.random.default_rng(20240601)
    robots = {n: RobotModel.from_config(n) for n in ('lbr4', 'icub_upper_body')}
    validator = jsonschema.Draft202012Validator(schema.load_schema())
    counts = {'accepted': 0, 'rejected': 0}
    worst = 0.0
    for k in range(N_DOCS):
        base = SEEDS[k % len(SEEDS)] if k % 3 else random_valid(rng)
        doc = mutate(base, rng) if rng.random() < 0.85 else copy.deepcopy(base)
        as_json = rng.random() < 0.3
        text = json.dumps(doc) if as_json else yaml.dump(doc, Dumper=DUMPER, sort_keys=False)
        if rng.random() < 0.3:
            text = mutate_text(text, rng)
        robot = robots['icub_upper_body' if 'icub' in json.dumps(base) else 'lbr4']
        t0 = time.process_time()  # CPU time: a pathological parse, not the machine's load
        try:
            stack = TaskStack.from_text(text)
            stack.validate(robot)
        except TaskStackError as exc:
            assert str(exc)
            counts['rejected'] += 1
        else:
            counts['accepted'] += 1
            if counts['accepted'] % 4 == 1:  # a sample: the schema check is slow
                validator.validate(stack.document.data)  # the data as loaded
                validator.validate(stack.to_dict())
        worst = max(worst, time.process_time() - t0)
        assert worst < MAX_SECONDS_PER_DOC, (k, text[:300])
    print(f'worst CPU time per document: {worst:.3f} s')
    assert counts['accepted'] > 500 and counts['rejected'] > 1500, counts
