"""Limits expressed as bounds on the virtual joint velocity."""

from ifc_spg.limits.joint_limits import VelocityBox, joint_velocity_bounds, intersect_soft

__all__ = ['VelocityBox', 'intersect_soft', 'joint_velocity_bounds']
