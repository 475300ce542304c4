"""Another node's live parameters, set from a tool (the cockpit's ``spg_node`` controls).

:func:`remote_parameters` picks one of two clients at construction, both with ``get(names,
callback)`` and ``set(name, value, timeout) -> SetParametersResult``:

- :class:`ServiceParameters` (rclpy): the rcl_interfaces ``GetParameters`` and
  ``SetParameters`` services of the node, as ``ros2 param get/set`` use them; a refused value
  comes back with the node's reason.
- :class:`EnableTopic` (built-in backend, which has no parameter services, README "Not
  mirrored on the built-in backend"): ``enable`` on the latched ``spg/enable`` Bool that
  ``spg_node`` subscribes on both backends; every other parameter is refused with the fix.
"""

from collections.abc import Callable
import threading
from typing import Any

from ifc_spg.ros.parameters import SetParametersResult

__all__ = ['EnableTopic', 'ServiceParameters', 'remote_parameters']


class ServiceParameters:
    """The parameter services of node ``target``, through rclpy clients made on ``node``.

    Relative names resolve in ``node``'s namespace; ``node`` must be spun elsewhere.
    """

    def __init__(self, node, target):
        from rcl_interfaces.srv import GetParameters, SetParameters

        self._get_type, self._set_type = GetParameters, SetParameters
        self.target = target
        self._get = node.create_client(GetParameters, f'{target}/get_parameters')
        self._put = node.create_client(SetParameters, f'{target}/set_parameters')

    def ready(self):
        """True once the node's parameter services are discovered."""
        return self._get.service_is_ready() and self._put.service_is_ready()

    def get(self, names, callback: Callable[[dict[str, Any]], None]):
        """Ask for ``names``; ``callback({name: value})`` runs in the spinning thread."""
        from rclpy.parameter import parameter_value_to_python

        future = self._get.call_async(self._get_type.Request(names=list(names)))

        def done(f):
            result = f.result()
            if result is not None:
                callback({n: parameter_value_to_python(v) for n, v in zip(names, result.values)})

        future.add_done_callback(done)

    def set(self, name, value, timeout=5.0):
        """Set ``name`` to ``value``: the node's SetParametersResult (reason if refused)."""
        from rclpy.parameter import Parameter

        if not self._put.wait_for_service(timeout_sec=timeout):
            return SetParametersResult(False, f"no parameter service '{self.target}/"
                                              "set_parameters': is spg_node running (on rclpy)?")
        request = self._set_type.Request(parameters=[Parameter(name, value=value)
                                                     .to_parameter_msg()])
        answered = threading.Event()
        future = self._put.call_async(request)
        future.add_done_callback(lambda _: answered.set())
        if not answered.wait(timeout):
            return SetParametersResult(False, f"'{self.target}' did not answer within "
                                              f'{timeout:g} s')
        result = future.result().results[0]
        return SetParametersResult(bool(result.successful), str(result.reason))


class EnableTopic:
    """``enable`` on the latched ``spg/enable`` Bool (no reply); the rest refused."""

    def __init__(self, node, target):
        from ifc_spg import ros
        from ifc_spg.ros import msg

        self.target, self._msg = target, msg
        self._pub = node.create_publisher(msg.Bool, 'spg/enable', ros.latched(1))

    def ready(self):
        """Never: there is nothing to read the values from."""
        return False

    def get(self, names, callback):
        """Nothing to read (no parameter services): ``callback`` is not called."""

    def set(self, name, value, timeout=5.0):
        """Publish ``enable`` on spg/enable; refuse every other parameter with the fix."""
        if name == 'enable':
            self._pub.publish(self._msg.Bool(data=bool(value)))
            return SetParametersResult(True, 'sent on spg/enable')
        return SetParametersResult(False, (
            f"cannot set '{name}': the built-in ROS backend has no parameter services; run "
            f"the cockpit with rclpy (IFC_SPG_ROS_BACKEND=rclpy) or restart {self.target} "
            f'with -p {name}:={value!r}'))


def remote_parameters(node, target='spg_node'):
    """The client for ``target``'s parameters this ROS backend supports (chosen once)."""
    from ifc_spg import ros

    return ServiceParameters(node, target) if ros.BACKEND == 'rclpy' else \
        EnableTopic(node, target)
