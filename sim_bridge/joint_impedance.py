"""Joint impedance IFC: the KUKA LBR FRI law (B.1) and the iCub variant (B.2, 3.3.2).

    τ = K (q_v − q) − D q̇ + τ_comp

The spring-damper part runs in MuJoCo actuators (one per joint, ``gain = K``,
``bias = −K q − D q̇``, ``ctrl = q_v``) so the damping is integrated implicitly
(``implicitfast``) and stays stable for any D; the compensation ``τ_comp`` goes to
``qfrc_applied`` every physics step:

- LBR FRI: gravity and dynamics compensation, ``τ_comp = qfrc_bias`` (gravity, Coriolis
  and centrifugal torques of the robot's own links and tool; never of what it touches).
- iCub: ``τ_comp = τ_offset``, a torque offset input (default: the same gravity and
  dynamics compensation). Joints marked stiff (the wrists) are position controlled by the
  same actuators with high gains (``stiff_gains``), i.e. no compliance.
"""

from dataclasses import dataclass

import numpy as np

from ifc_spg.errors import ParameterError

__all__ = ['JointImpedance']


@dataclass
class JointImpedance:
    """The joint impedance law of LBR FRI (``stiff_mask`` all False) and iCub.

    Attributes:
        stiffness: Joint stiffness K in [Nm/rad] per joint.
        damping: Joint damping D in [Nms/rad] per joint.
        stiff_mask: True for position-controlled (stiff) joints.
        stiff_gains: (K_p [Nm/rad], K_d [Nms/rad]) of the stiff joints' position loop.
        name: ``'lbr_fri'`` or ``'icub'`` (for messages).
    """

    stiffness: np.ndarray
    damping: np.ndarray
    stiff_mask: np.ndarray
    stiff_gains: tuple = (2000.0, 20.0)
    name: str = 'lbr_fri'

    def setup(self, sim):
        """Write the actuator gains into ``sim.model`` (call again after changing K/D)."""
        kp = np.where(self.stiff_mask, self.stiff_gains[0], self.stiffness)
        kd = np.where(self.stiff_mask, self.stiff_gains[1], self.damping)
        m = sim.model
        for i, a in enumerate(sim.actuator_ids):
            m.actuator_gainprm[a, 0] = kp[i]
            m.actuator_biasprm[a, :3] = (0.0, -kp[i], -kd[i])
        self._tau_offset = None

    def set_gains(self, sim, stiffness=None, damping=None):
        """Change K and/or D at run time (as FRI allows between commands)."""
        n = len(sim.joint_names)
        if stiffness is not None:
            self.stiffness = _vector(stiffness, n, 'stiffness')
        if damping is not None:
            self.damping = _vector(damping, n, 'damping')
        self.setup(sim)

    def reset(self, sim, q0):
        """Hold ``q0``: ctrl = q0, no torque offset."""
        sim.data.ctrl[sim.actuator_index] = q0
        self._tau_offset = None

    def command(self, sim, q_v, qd_v=None, tau_offset=None):
        """Latch a new q_v (zero-order hold) and, for the iCub, a torque offset in [Nm]."""
        sim.data.ctrl[sim.actuator_index] = q_v
        if tau_offset is not None:
            self._tau_offset = _vector(tau_offset, len(sim.joint_names), 'tau_offset')

    def control(self, sim):
        """Per physics step (after ``mj_step1``): write the compensation torque."""
        d = sim.data
        if self._tau_offset is None:
            d.qfrc_applied[sim.dof_index] = d.qfrc_bias[sim.dof_index]
        else:
            d.qfrc_applied[sim.dof_index] = self._tau_offset


def _vector(x, n, what):
    a = np.broadcast_to(np.asarray(x, dtype=float), (n,)).copy() if np.ndim(x) == 0 else \
        np.asarray(x, dtype=float).reshape(-1)
    if a.shape != (n,) or not np.all(np.isfinite(a)):
        raise ParameterError(f'{what} must be {n} finite numbers (or one), got {x!r}')
    return a
