"""The console entry points: signal handling first, then the heavy imports.

``spg_node``, ``sim_bridge``, ``task_publisher`` and ``ifc-spg`` start here. Before anything
else is imported (pinocchio, MuJoCo, DDS take 1-3 s on a small machine), SIGINT and SIGTERM
are made to interrupt the program: a process started in the background by a non-interactive
shell inherits SIGINT *ignored*, and Python keeps it ignored, so without this a Ctrl-C or
``kill -INT`` during start-up was lost and the node went on to command the robot. A signal
during start-up ends the process with a one-line message and exit status 0, before it
publishes anything; later, each program's own handling takes over (the nodes stop their loop
and print their summary line). What no program can catch: the interpreter's own start
(0.05-0.3 s, before this module runs), where SIGTERM ends the process by its default action
(status 143, before anything is published) and an inherited-ignored SIGINT is lost.
The node programs and ``ifc-spg bag`` end without the interpreter's finalization once they
have shut their ROS context down (:func:`_quick_exit`).
"""

from collections.abc import Callable
import importlib
import os
import signal
import sys

__all__ = ['ifc_spg', 'sim_bridge', 'spg_node', 'task_publisher']


def _run(name: str, target: str, status: int | None = 0, gl: bool = False,
         quick_exit: bool = False) -> int:
    """Run ``target`` ('module:function'), ending at once on a signal until it takes over.

    Until the program installs its own handlers (the nodes do when their loop starts, the
    recorder when it records), SIGINT and SIGTERM print one line and end the process with
    ``status`` (None: 128 + the signal number, the shell's convention for an interrupted
    command) by ``os._exit``: an exception raised from a handler in the middle of an import
    can surface as an unrelated ImportError (numpy's C modules turn it into one), and there
    is nothing to clean up yet. ``gl``: the program renders with MuJoCo (else MuJoCo is
    imported without a GL backend unless ``MUJOCO_GL`` is set). ``quick_exit``: a node
    program, which ends by :func:`_quick_exit` once its ``main`` returned.
    """
    def stop(signum: int, frame: object) -> None:
        sig = signal.Signals(signum)
        os.write(2, f'{name}: stopped by {sig.name} during start-up\n'.encode())
        os._exit(128 + signum if status is None else status)

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, stop)
    if not gl:
        # MuJoCo picks a GL backend when it is imported; with MUJOCO_GL unset that is GLFW,
        # whose import starts a Python child to read the library's version (~50 ms), and a
        # signal during start-up left that child writing into its closed pipe (a
        # BrokenPipeError traceback in the program's output). Programs that never render
        # import MuJoCo without GL; a MUJOCO_GL the user set is kept.
        os.environ.setdefault('MUJOCO_GL', 'disable')
    # one BLAS thread: the programs' matrices are small and their parallel work runs in
    # processes, while OpenBLAS's worker threads cost CPU of their own (measured on 2 cores:
    # importing the SPG took 0.67 s of CPU with them, 0.41 s without); a value the user set
    # is kept
    os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')
    module, func = target.split(':')
    main: Callable[[], int | None] = getattr(importlib.import_module(module), func)
    code = int(main() or 0)
    if quick_exit:
        _quick_exit(code)
    return code


def _quick_exit(code: int) -> None:
    """End the process now, with ``code``, once a node has shut its ROS context down.

    By then each program has closed what it wrote (bags, logs) and destroyed its nodes and
    DDS participants (their shared-memory segments go with them); what is left is the
    interpreter's finalization, in which Fast DDS' static objects join their threads: 0.2-1.4 s
    after a plain rclpy script had shut down (measured on 2 cores), which every start/stop of
    a node set and every Ctrl-C waited for. Python's and C's output buffers are flushed
    first; atexit handlers do not run (the node programs register none of their own).
    """
    import ctypes
    import logging

    logging.shutdown()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # closed, or its reader is gone
            pass
    try:
        ctypes.CDLL(None).fflush(None)  # C stdio (rcutils' console output)
    except (OSError, AttributeError):
        pass
    os._exit(code)


def spg_node() -> int:
    """``spg_node``: :func:`ifc_spg.node.spg_node.main`."""
    return _run('spg_node', 'ifc_spg.node.spg_node:main', quick_exit=True)


def sim_bridge() -> int:
    """``sim_bridge``: :func:`sim_bridge.node.main`."""
    return _run('sim_bridge', 'sim_bridge.node:main', quick_exit=True)


def task_publisher() -> int:
    """``task_publisher``: :func:`ifc_spg.cli.task_publisher.main`."""
    return _run('task_publisher', 'ifc_spg.cli.task_publisher:main', quick_exit=True)


def ifc_spg() -> int:
    """``ifc-spg``: :func:`ifc_spg.cli.main`.

    ``ifc-spg bag`` (record, play) ends with status 0 on a signal, and as quickly, like the
    nodes; the other verbs, interrupted before they install handlers of their own, with 128 +
    the signal.
    """
    verb = sys.argv[1] if len(sys.argv) > 1 else ''
    # render draws with MuJoCo (MUJOCO_GL=egl unless set); demo's render child takes the env
    return _run('ifc-spg', 'ifc_spg.cli:main', 0 if verb == 'bag' else None,
                gl=verb in ('render', 'demo'), quick_exit=verb == 'bag')
