"""Trajectory generators: analytic rates vs finite differences, anchors, and their use in tasks."""

import numpy as np
import pytest

from ifc_spg.errors import IfcSpgError
from ifc_spg.model import RobotModel
from ifc_spg.task_stack import TaskStack
from ifc_spg.task_stack.trajectories import (
    Anchor,
    Circle,
    Ramp,
    Sine,
    SquareWave,
    min_jerk,
)

RNG = np.random.default_rng(4)


def generators():
    init = RNG.normal(size=5)
    yield 'circle', Circle(5, plane=(1, 3), radius=0.2, frequency=0.7, phase=0.3), init
    yield 'circle_center', Circle(5, plane=(0, 1), radius=0.1, frequency=-0.4,
                                  center=Anchor([0.5, 0.0], [False, True])), init
    yield 'sine', Sine(5, amplitude=RNG.uniform(0, 1, 5), frequency=RNG.uniform(0, 2, 5),
                       phase=RNG.uniform(-3, 3, 5), offset=RNG.normal(size=5)), init
    yield 'square', SquareWave(5, offsets=RNG.normal(size=(2, 5)), period=2.0, duty=0.3,
                               transition=0.4), init
    yield 'ramp', Ramp(5, duration=1.5, delay=0.2, delta=RNG.normal(size=5)), init
    yield 'min_jerk', Ramp(5, duration=1.5, delay=0.2, end=Anchor(RNG.normal(size=5)),
                           profile='min_jerk'), init


@pytest.mark.parametrize('name,gen,init', list(generators()), ids=lambda x: x
                         if isinstance(x, str) else '')
def test_rate_is_the_derivative(name, gen, init):
    active = gen.activate(init)
    h = 1e-6
    for t in np.linspace(0.0, 6.0, 301)[1:] + 1e-3:  # off the ramp's kinks
        v, r = active.evaluate(t)
        assert v.shape == r.shape == (5,)
        vp, _ = active.evaluate(t + h)
        vm, _ = active.evaluate(t - h)
        fd = (vp - vm) / (2 * h)
        if name == 'square' and np.abs(fd).max() > 1e3:
            continue  # a step (none here: transition > 0), skip the discontinuity
        np.testing.assert_allclose(r, fd, atol=1e-5, rtol=1e-5, err_msg=f'{name} t={t}')


def test_starts_at_init_and_keeps_other_components():
    init = np.array([0.1, 0.2, 0.3, 0.4, 0.5])
    for name, gen, _ in generators():
        if name == 'circle_center':
            continue
        v0, _ = gen.activate(init).evaluate(0.0)
        if name == 'sine':
            v0 = v0 - gen.offset - gen.amplitude * np.sin(gen.phase)
        if name == 'square':
            v0 = v0 - gen.offsets[0]
        np.testing.assert_allclose(v0, init, atol=1e-12, err_msg=name)
    c = Circle(5, plane=(1, 3), radius=0.2, frequency=0.5).activate(init)
    for t in np.linspace(0, 3, 17):
        v, _ = c.evaluate(t)
        np.testing.assert_allclose(v[[0, 2, 4]], init[[0, 2, 4]])
        centre = init[[1, 3]] - [0.2, 0.0]
        assert abs(np.hypot(*(v[[1, 3]] - centre)) - 0.2) < 1e-12
    # the spec object is not changed by activation (reusable)
    spec = Circle(5, plane=(1, 3), radius=0.2, frequency=0.5)
    first = spec.activate(init)
    with pytest.raises(IfcSpgError, match='activate'):
        spec.evaluate(0.0)
    again = spec.activate(init + 1.0)
    np.testing.assert_allclose(again.evaluate(0.7)[0], first.evaluate(0.7)[0] + 1.0)


def test_square_wave_levels_and_ramp_end():
    sq = SquareWave(2, offsets=[[0, 0], [0, 0.08]], period=8.0).activate(np.array([1.0, 2.0]))
    assert sq.evaluate(1.0)[0].tolist() == [1.0, 2.0]
    assert sq.evaluate(5.0)[0].tolist() == [1.0, 2.08]
    assert sq.evaluate(9.0)[0].tolist() == [1.0, 2.0]
    r = Ramp(2, duration=2.0, end=Anchor([3.0, 0.0], [False, True]), end_same=[False, True])
    r = r.activate(np.array([1.0, 2.0]))
    assert r.evaluate(-1.0)[0].tolist() == [1.0, 2.0]
    np.testing.assert_allclose(r.evaluate(1.0), ([2.0, 2.0], [1.0, 0.0]))
    assert r.evaluate(5.0)[0].tolist() == [3.0, 2.0]
    assert min_jerk(0.5) == (0.5, 1.875)
    with pytest.raises(IfcSpgError, match='activate'):
        Sine(2, amplitude=1, frequency=1).evaluate(0.0)


def test_trajectory_in_a_task_follows_the_spec():
    """Bounds built from YAML evaluate to the formula of Table 3.2 / 3.3 / 3.7."""
    robot = RobotModel.from_config('lbr4')
    text = """
version: 1
tasks:
  - type: cartesian_pose
    frame: tool
    subspace: [x, y, rx, ry, rz]
    equal: {trajectory: lissajous, amplitude: {x: 0.1, y: 0.03}, frequency: {x: 0.1, y: 0.4},
            phase: {x: 1.5707963267948966}, offset: {x: -0.1}}
  - type: joint_position
    joints: [A1, A2]
    equal: {trajectory: min_jerk, to: {A2: 0.5}, duration: 2.0}
"""
    pose, joints = TaskStack.from_yaml(text).build(robot)
    init = np.array([0.5, 0.1, 0.0, 0.0, 0.0])
    b = pose.lower_bound.activate(init)
    for t in (0.0, 0.7, 3.1):
        x = init[0] + 0.1 * np.cos(2 * np.pi * 0.1 * t) - 0.1
        y = init[1] + 0.03 * np.sin(2 * np.pi * 0.4 * t)
        np.testing.assert_allclose(b.evaluate(t)[0], [x, y, 0, 0, 0], atol=1e-12)
    j = joints.lower_bound.activate(np.array([0.2, 0.1]))
    np.testing.assert_allclose(j.evaluate(0.0)[0], [0.2, 0.1])
    np.testing.assert_allclose(j.evaluate(1.0)[0], [0.2, 0.3])
    np.testing.assert_allclose(j.evaluate(2.5)[0], [0.2, 0.5])
