"""StopSignals: a signal ends the loop even where an extension turned its KeyboardInterrupt
into another exception (ifc_spg/ros/signals.py)."""

import os
import signal
import time

import pytest

from ifc_spg.ros.signals import StopSignals


def _pybind11_like():
    """What rclpy's take_message does when a signal lands in its message conversion."""
    try:
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(1.0)  # the handler runs here and raises
    except KeyboardInterrupt:
        raise RuntimeError("Unable to convert call argument '0' to Python object") from None


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM])
def test_a_signal_raises_keyboard_interrupt_and_is_a_stop(sig):
    before = signal.getsignal(sig)
    with StopSignals() as stops:
        with pytest.raises(KeyboardInterrupt) as info:
            os.kill(os.getpid(), sig)
            time.sleep(1.0)
        assert stops.received == sig
        assert stops.stopped_by(info.value)
    assert signal.getsignal(sig) is before  # the previous handler is back


def test_an_exception_after_a_signal_is_a_stop_and_before_it_an_error():
    with StopSignals() as stops:
        assert not stops.stopped_by(RuntimeError('a real error'))
        with pytest.raises(RuntimeError) as info:
            _pybind11_like()
        assert stops.received == signal.SIGTERM
        assert stops.stopped_by(info.value)


def test_ignore_keeps_a_second_signal_from_the_clean_up():
    with StopSignals() as stops:
        stops.ignore()
        os.kill(os.getpid(), signal.SIGTERM)  # ignored: nothing raised, the test goes on
        time.sleep(0.05)
        assert stops.received is None
