"""Small closed-loop plants for tests and benchmarks (no simulator needed).

:class:`JointImpedancePlant` integrates a rigid robot under an ideal joint-impedance IFC
(docs/SPEC.md §1, thesis B.1) with perfect gravity and Coriolis compensation::

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
        """Advance one period holding the set-point ``q_v``; returns ``(q, qdot, t)``.

        Each substep is implicit in the spring (midpoint position) and the damper (new
        velocity), so the discrete energy balance of the IFC port is exact: the work
        booked in :attr:`work_in` is -sum tau (q_{k+1} - q_k) with
        tau = K (q_v - q_mid) - D qdot_{k+1}, and the spring energy changes by exactly the
        spring part of it.
        """
        h = self.dt / self.substeps
        n = self.robot.n
        tau_ext = np.zeros(n) if tau_ext is None else np.asarray(tau_ext, dtype=float)
        for _ in range(self.substeps):
            if self.inertia is None:
                M = pin.crba(self.robot.model, self.data, self.q)
                M = np.triu(M) + np.triu(M, 1).T
            else:
                M = np.diag(self.inertia)
            lhs = M + np.diag(0.5 * h * h * self.K + h * self.D)
            rhs = M @ self.qdot + h * (self.K * (q_v - self.q) + tau_ext)
            qdot_new = np.linalg.solve(lhs, rhs)
            q_new = self.q + h * qdot_new
            tau = self.K * (q_v - 0.5 * (self.q + q_new)) - self.D * qdot_new
            self.work_in -= tau * (q_new - self.q)
            self.q, self.qdot = q_new, qdot_new
        self.t += self.dt
        return self.q.copy(), self.qdot.copy(), self.t
