"""Small chain models for the dynamics solver.

The report's 1-DoF arm, an iiwa-like arm and random chains (for tests and the O(n)
benchmark).

All models are built as URDF text and parsed by pinocchio, so fixed joints are folded
into their parent segment exactly as for a user's URDF file.
"""

import numpy as np
import pinocchio as pin

__all__ = ['one_dof_arm', 'iiwa_like_model', 'random_chain_model', 'random_chain_urdf',
           'planar_arm']

_INERTIAL = ('<inertial><origin xyz="{c[0]:.17g} {c[1]:.17g} {c[2]:.17g}" rpy="0 0 0"/>'
             '<mass value="{m:.17g}"/><inertia ixx="{I[0][0]:.17g}" ixy="{I[0][1]:.17g}" '
             'ixz="{I[0][2]:.17g}" iyy="{I[1][1]:.17g}" iyz="{I[1][2]:.17g}" '
             'izz="{I[2][2]:.17g}"/></inertial>')


def _link(name, mass=None, com=(0, 0, 0), inertia=None):
    if mass is None:
        return f'<link name="{name}"/>'
    inertia = np.zeros((3, 3)) if inertia is None else np.asarray(inertia)
    return f'<link name="{name}">' + _INERTIAL.format(c=com, m=mass, I=inertia) + '</link>'


def _joint(name, kind, parent, child, xyz=(0, 0, 0), rpy=(0, 0, 0), axis=(0, 0, 1)):
    limit = ('<limit lower="-3.1" upper="3.1" effort="300" velocity="10"/>'
             if kind in ('revolute', 'prismatic') else '')
    ax = '' if kind == 'fixed' else '<axis xyz="{:.17g} {:.17g} {:.17g}"/>'.format(*axis)
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/>'
            f'<child link="{child}"/>'
            '<origin xyz="{:.17g} {:.17g} {:.17g}" rpy="{:.17g} {:.17g} {:.17g}"/>'.format(
                *xyz, *rpy) + ax + limit + '</joint>')


def _build(links, joints, name):
    text = f'<robot name="{name}">' + ''.join(links) + ''.join(joints) + '</robot>'
    return pin.buildModelFromXML(text), text


def one_dof_arm(*, mass=1.0, length=1.0, com=0.5, inertia_com=0.0, armature=0.0):
    """The report's Ch. 6 arm: one revolute joint about z, link along x, tip frame at x = L.

    Args:
        mass: Link mass in [kg].
        length: Link length in [m] (tip frame ``tip`` at x = length).
        com: Distance of the centre of mass from the joint in [m].
        inertia_com: Rotational inertia about the COM around z in [kg m^2] (0 = point mass,
            as the report's KDL model, whose ``RotationalInertia`` defaults to zero).
        armature: Rotor inertia in [kg m^2].

    Returns:
        pinocchio Model with joint ``joint1`` and frame ``tip``. No gravity is assumed by
        the scenarios (they pass a zero base acceleration).
    """
    inertia = np.diag([inertia_com, inertia_com, inertia_com])
    links = [_link('base'), _link('link1', mass, (com, 0, 0), inertia), _link('tip')]
    joints = [_joint('joint1', 'revolute', 'base', 'link1'),
              _joint('tip_joint', 'fixed', 'link1', 'tip', xyz=(length, 0, 0))]
    model, _ = _build(links, joints, 'one_dof_arm')
    model.armature[:] = armature
    return model


def planar_arm(n, *, mass=1.0, length=0.4, armature=0.0):
    """An n-link planar arm (joints about z, links along x, uniform rods) with frame ``tip``."""
    Ic = mass * length ** 2 / 12.0
    links = [_link('base')]
    joints = []
    parent = 'base'
    for i in range(n):
        links.append(_link(f'link{i + 1}', mass, (length / 2, 0, 0),
                           np.diag([1e-4, Ic, Ic])))
        joints.append(_joint(f'joint{i + 1}', 'revolute', parent, f'link{i + 1}',
                             xyz=(0 if i == 0 else length, 0, 0)))
        parent = f'link{i + 1}'
    links.append(_link('tip'))
    joints.append(_joint('tip_joint', 'fixed', parent, 'tip', xyz=(length, 0, 0)))
    model, _ = _build(links, joints, f'planar{n}')
    model.armature[:] = armature
    return model


# iiwa 14-like kinematics and inertias (rounded from the public iiwa14 description).
_IIWA = [  # (xyz, rpy, mass, com, (ixx, iyy, izz))
    ((0, 0, 0.1575), (0, 0, 0), 5.76, (0, -0.03, 0.12), (0.033, 0.0333, 0.0123)),
    ((0, 0, 0.2025), (np.pi / 2, 0, np.pi), 6.35, (0.0003, 0.059, 0.042),
     (0.0305, 0.0304, 0.011)),
    ((0, 0.2045, 0), (np.pi / 2, 0, np.pi), 3.5, (0, 0.03, 0.13), (0.025, 0.0238, 0.0076)),
    ((0, 0, 0.2155), (np.pi / 2, 0, 0), 3.5, (0, 0.067, 0.034), (0.017, 0.0164, 0.006)),
    ((0, 0.1845, 0), (-np.pi / 2, np.pi, 0), 3.5, (0.0001, 0.021, 0.076),
     (0.01, 0.0087, 0.00449)),
    ((0, 0, 0.2155), (np.pi / 2, 0, 0), 1.8, (0, 0.0006, 0.0004), (0.0049, 0.0047, 0.0036)),
    ((0, 0.081, 0), (-np.pi / 2, np.pi, 0), 1.2, (0, 0, 0.02), (0.001, 0.001, 0.001)),
]


def iiwa_like_model(*, armature=(0.4, 0.4, 0.3, 0.3, 0.1, 0.1, 0.05), tool_mass=0.3):
    """A 7-DoF KUKA LBR iiwa 14-like arm with a tool (fixed joint, folded) and frame ``tool``."""
    links = [_link('iiwa_link_0', 5.0, (-0.1, 0, 0.07), np.diag([0.05, 0.06, 0.03]))]
    joints = []
    parent = 'iiwa_link_0'
    for i, (xyz, rpy, m, com, diag) in enumerate(_IIWA):
        child = f'iiwa_link_{i + 1}'
        links.append(_link(child, m, com, np.diag(diag)))
        joints.append(_joint(f'iiwa_joint_{i + 1}', 'revolute', parent, child, xyz, rpy))
        parent = child
    links.append(_link('tool_body', tool_mass, (0, 0, 0.03), np.diag([1e-4, 1e-4, 1e-4])))
    joints.append(_joint('tool_mount', 'fixed', parent, 'tool_body', xyz=(0, 0, 0.045)))
    links.append(_link('tool'))
    joints.append(_joint('tool_tip', 'fixed', 'tool_body', 'tool', xyz=(0, 0, 0.1)))
    model, _ = _build(links, joints, 'iiwa_like')
    model.armature[:] = armature
    return model


def _random_inertia(rng):
    """A physically valid random rotational inertia (triangle inequality holds)."""
    a = rng.uniform(0.05, 1.0, 3) * rng.uniform(0.005, 0.1)
    principal = np.array([a[1] + a[2], a[0] + a[2], a[0] + a[1]])   # sums of mass moments
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return Q @ np.diag(principal) @ Q.T


def random_chain_urdf(rng, n, *, p_prismatic=0.25, p_fixed=0.2, p_aligned=0.3):
    """URDF text of a random serial chain with ``n`` moving joints.

    Joints get random axes (some axis-aligned), origins and orientations; a fraction is
    prismatic; fixed joints with massive links are inserted at random (pinocchio folds them).
    A frame ``tip`` sits behind a fixed joint at the end.
    """
    links = [_link('base')]
    joints = []
    parent = 'base'
    k = 0
    j = 0
    while k < n:
        kind = 'fixed' if (j > 0 and rng.random() < p_fixed) else (
            'prismatic' if rng.random() < p_prismatic else 'revolute')
        if rng.random() < p_aligned:
            axis = np.eye(3)[rng.integers(3)] * rng.choice([-1, 1])
        else:
            axis = rng.normal(size=3)
            axis /= np.linalg.norm(axis)
        child = f'l{j}'
        links.append(_link(child, rng.uniform(0.2, 3.0), rng.uniform(-0.2, 0.2, 3),
                           _random_inertia(rng)))
        joints.append(_joint(f'j{j}', kind, parent, child, rng.uniform(-0.3, 0.3, 3),
                             rng.uniform(-np.pi, np.pi, 3), axis))
        parent = child
        j += 1
        if kind != 'fixed':
            k += 1
    links.append(_link('tip'))
    joints.append(_joint('tip_joint', 'fixed', parent, 'tip', rng.uniform(-0.2, 0.2, 3),
                         rng.uniform(-np.pi, np.pi, 3)))
    return f'<robot name="random{n}">' + ''.join(links) + ''.join(joints) + '</robot>'


def random_chain_model(rng, n, *, armature=True, **kwargs):
    """Parse :func:`random_chain_urdf` and give it random rotor inertias."""
    model = pin.buildModelFromXML(random_chain_urdf(rng, n, **kwargs))
    if armature:
        model.armature[:] = rng.uniform(0.0, 0.2, model.nv)
    return model
