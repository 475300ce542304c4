"""Collision geometry of the robot models and of known obstacles (pinocchio + coal)."""

from ifc_spg.geometry.collision import (
    OBSTACLE_SHAPES,
    CollisionGeometry,
    Distances,
    Obstacle,
    PairQuery,
    rpy_matrix,
)

__all__ = ['OBSTACLE_SHAPES', 'CollisionGeometry', 'Distances', 'Obstacle', 'PairQuery',
           'rpy_matrix']
