"""Limits expressed as bounds on the virtual joint velocity."""

from ifc_spg.limits.joint_limits import (
    JointVelocityLimits,
    VelocityBox,
    intersect_soft,
    joint_velocity_bounds,
    stopping_velocity,
)

__all__ = ['JointVelocityLimits', 'VelocityBox', 'intersect_soft', 'joint_velocity_bounds',
           'stopping_velocity']
