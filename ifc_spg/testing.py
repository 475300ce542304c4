"""Small closed-loop plants for tests and benchmarks (no simulator needed).

:class:`JointImpedancePlant` integrates a rigid robot under an ideal joint-impedance IFC
(SPEC B.1) with perfect gravity and Coriolis compensation::

    M(q) qddot = K (q_v - q) - D qdot + tau_ext

with ``substeps`` semi-implicit Euler steps per SPG period. It also integrates the energy
flow -int tau qdot dt of the IFC torque tau = K (q_v - q) - D qdot per joint, the left
side of the passivity inequality (4.84).
"""

import numpy as np
import pinocchio as pin

__all__ = ['JointImpedancePlant']


class JointImpedancePlant:
    """Joint-impedance plant with perfect gravity/dynamics compensation.

    Args:
        robot: The :class:`~ifc_spg.model.RobotModel`.
        q0: Initial joint positions in [rad].
        dt: Period of one :meth:`step` in [s] (the SPG period).
        substeps: Integration substeps per period.
        stiffness, damping: Override K, D (default: the robot's).
        diagonal_inertia: Use a constant diagonal inertia in [kg m^2] instead of M(q).
    """

    def __init__(self, robot, q0, dt=0.002, substeps=10, stiffness=None, damping=None,
                 diagonal_inertia=None):
        self.robot = robot
        self.data = robot.create_data()
        self.q = np.array(q0, dtype=float)
        self.qdot = np.zeros(robot.n)
        self.t = 0.0
        self.dt = float(dt)
        self.substeps = int(substeps)
        self.K = np.array(robot.stiffness if stiffness is None else stiffness, dtype=float)
        self.D = np.array(robot.damping if damping is None else damping, dtype=float)
        self.inertia = None if diagonal_inertia is None else np.asarray(diagonal_inertia, float)
        self.work_in = np.zeros(robot.n)  # -int tau qdot dt per joint [J]

    def step(self, q_v, tau_ext=None):
        """Advance one period holding the set-point ``q_v``; returns ``(q, qdot, t)``."""
        h = self.dt / self.substeps
        tau_ext = np.zeros(self.robot.n) if tau_ext is None else tau_ext
        for _ in range(self.substeps):
            tau = self.K * (q_v - self.q) - self.D * self.qdot
            if self.inertia is None:
                Minv = pin.computeMinverse(self.robot.model, self.data, self.q)
                Minv = np.triu(Minv) + np.triu(Minv, 1).T
                qdd = Minv @ (tau + tau_ext)
            else:
                qdd = (tau + tau_ext) / self.inertia
            qdot_new = self.qdot + h * qdd
            # energy flow with the midpoint velocity of this substep
            self.work_in -= tau * 0.5 * (self.qdot + qdot_new) * h
            self.qdot = qdot_new
            self.q = self.q + h * self.qdot
        self.t += self.dt
        return self.q.copy(), self.qdot.copy(), self.t
