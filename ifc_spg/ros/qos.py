"""QoS profiles with rclpy's names and defaults, and their Cyclone DDS translation.

``QoSProfile(depth=10)`` is reliable, volatile, keep-last; ``qos_profile_sensor_data`` is
best effort, volatile, depth 5; ``latched(depth=1)`` is reliable, transient local, depth 1 (what
``rclpy`` users build as ``QoSProfile(depth=1, durability=TRANSIENT_LOCAL)``). The DDS QoS is
built as ``rmw_cyclonedds_cpp``'s ``create_readwrite_qos`` does: KEEP_LAST(depth), reliable with
infinite max blocking time, transient local with a matching durability service history,
autodispose off, automatic liveliness, and ``typehash=RIHS01_...;`` in USER_DATA.
"""

import dataclasses
import enum

from ifc_spg.errors import ParameterError

__all__ = ['ReliabilityPolicy', 'DurabilityPolicy', 'HistoryPolicy', 'QoSProfile',
           'qos_profile_sensor_data', 'qos_profile_system_default', 'latched', 'as_qos',
           'to_dds_qos']


class ReliabilityPolicy(enum.IntEnum):
    """rmw reliability kinds (values as rmw)."""

    SYSTEM_DEFAULT = 0
    RELIABLE = 1
    BEST_EFFORT = 2


class HistoryPolicy(enum.IntEnum):
    """rmw history kinds (values as rmw)."""

    SYSTEM_DEFAULT = 0
    KEEP_LAST = 1
    KEEP_ALL = 2


class DurabilityPolicy(enum.IntEnum):
    """rmw durability kinds (values as rmw)."""

    SYSTEM_DEFAULT = 0
    TRANSIENT_LOCAL = 1
    VOLATILE = 2


@dataclasses.dataclass(frozen=True)
class QoSProfile:
    """A ROS 2 QoS profile (the subset of rclpy.qos.QoSProfile the nodes use).

    Attributes:
        depth: History depth (KEEP_LAST) [messages].
        reliability: ReliabilityPolicy.
        durability: DurabilityPolicy.
        history: HistoryPolicy.
    """

    depth: int = 10
    reliability: ReliabilityPolicy = ReliabilityPolicy.RELIABLE
    durability: DurabilityPolicy = DurabilityPolicy.VOLATILE
    history: HistoryPolicy = HistoryPolicy.KEEP_LAST

    def __post_init__(self) -> None:
        if self.history != HistoryPolicy.KEEP_ALL and not (
                isinstance(self.depth, int) and self.depth >= 1):
            raise ParameterError(f'QoS depth {self.depth!r} is invalid: KEEP_LAST needs an int '
                                 '>= 1 (e.g. QoSProfile(depth=10))')


qos_profile_sensor_data = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
qos_profile_system_default = QoSProfile(depth=1)


def latched(depth: int = 1) -> QoSProfile:
    """Reliable, transient-local, keep-last ``depth`` profile (late joiners get the last ones)."""
    return QoSProfile(depth=depth, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def as_qos(qos: 'QoSProfile | int') -> QoSProfile:
    """Accept a QoSProfile or an int depth (as rclpy's create_publisher does)."""
    if isinstance(qos, QoSProfile):
        return qos
    if isinstance(qos, int) and not isinstance(qos, bool):
        return QoSProfile(depth=qos)
    raise ParameterError(f'QoS must be a QoSProfile or an int depth, got {qos!r}')


def to_dds_qos(qos, type_hash, extra_user_data=b''):
    """Translate to a cyclonedds Qos exactly as rmw_cyclonedds_cpp's create_readwrite_qos.

    Args:
        qos: QoSProfile.
        type_hash: ``'RIHS01_<hex>'`` of the message type ('' to omit).
        extra_user_data: Bytes prepended to the USER_DATA.
    """
    from cyclonedds.qos import Policy, Qos
    from cyclonedds.util import duration

    infinite = duration(infinite=True)
    if qos.history == HistoryPolicy.KEEP_ALL:
        history = Policy.History.KeepAll
    else:
        history = Policy.History.KeepLast(qos.depth)
    policies = [Policy.WriterDataLifecycle(autodispose=False), history]
    if qos.reliability == ReliabilityPolicy.BEST_EFFORT:
        policies.append(Policy.Reliability.BestEffort)
    else:
        policies.append(Policy.Reliability.Reliable(max_blocking_time=infinite))
    if qos.durability == DurabilityPolicy.TRANSIENT_LOCAL:
        policies.append(Policy.Durability.TransientLocal)
        policies.append(Policy.DurabilityService(
            cleanup_delay=0, history=history, max_samples=-1, max_instances=-1,
            max_samples_per_instance=-1))
    else:
        policies.append(Policy.Durability.Volatile)
    policies.append(Policy.Liveliness.Automatic(lease_duration=infinite))
    user_data = extra_user_data + (f'typehash={type_hash};'.encode() if type_hash else b'')
    policies.append(Policy.Userdata(data=user_data))
    # rmw_cyclonedds' serdata is plain CDR (XCDR1); say so, the Python default may differ
    policies.append(Policy.DataRepresentation(use_cdrv0_representation=True))
    return Qos(*policies)
