"""Tick-to-command latency of a realtime DDS run, per pairing of the two ROS backends.

``sim_bridge`` (realtime, 500 or 1000 Hz, iiwa, free scene) and ``spg_node`` run as separate
processes over loopback DDS, for each pairing of the two ROS backends (rclpy on Fast DDS, the
built-in Cyclone DDS backend) in one invocation::

    python -m benchmarks.latency_bench [--seconds 60] [--rate 500,1000]
                                          [--pairs all|same|BRIDGE:SPG,...]
                                          [--spg-paths wait_set,executor,events]
                                          [--listener off|on|both]
                                          [--baseline-seconds S] [--nice N] [--fifo PRIO]
                                          [--json]

``--spg-paths`` runs each pairing with the SPG on rclpy once per way of serving its joint
states: ``wait_set`` (the node's default, ``hot_path:=wait_set``), ``executor``
(``hot_path:=executor``, rclpy's SingleThreadedExecutor) and ``events`` (the same with
``IFC_SPG_RCLPY_EXECUTOR=events``: rclpy's experimental EventsExecutor).

Beside them, once per rate and in this process, the machine's own baseline: a plain Python
loop pacing the same rate with absolute deadlines and ``time.sleep``, its overshoot
p50/p99/max and the periods it missed (woke after the next deadline). On a shared machine
the ratio of a pairing's missed periods and p99 to the baseline's is what a run can show.

The latency of a tick is measured by the bridge on its own clock: from publishing a state to
receiving the command answering it (same header stamp) — the bridge's publish, the SPG's tick
and the command's way back over loopback DDS, as the robot sees it. Reported per pairing:
p50/p99/max [ms], missed periods (the bridge's count of command periods without a new
command, from its exit line; the goal on an idle machine is <= 0.1 % over 60 s), the bridge's
pacing, and the SPG process' CPU time per tick over the run (all its threads; Linux). With
``--listener on`` this process also subscribes to the states and commands and counts what it
saw: a third reader of both topics, as a recorder would be, which costs the SPG a second
command publish and the machine this process' executor (off by default: the two nodes alone).
"""

import argparse
import json
import os
from pathlib import Path
import re
import subprocess
import sys
import tempfile
import time

from ros_testing import loopback_env, random_domain_id, stop_process

from ifc_spg import ros
from ifc_spg.offline.runner import find_config_dir
from ifc_spg.ros import dds, messages
from ifc_spg.ros.stamps import stamp_to_ns

__all__ = ['PAIRS', 'SPG_PATHS', 'baseline', 'main', 'run']

STACK = """version: 1
name: reach
robot: lbr_iiwa14
tasks:
  - name: posture
    type: joint_position
    equal: [0.3, 0.7, 0.2, -0.9, 0.1, 1.2, 0.3]
    gain: 1.0
"""


def _stamp(msg):
    return stamp_to_ns(msg.header.stamp)


class _Listener:
    """The stamps of the states and commands seen on one backend, in this process.

    Each listener has its own context, so that both backends can listen in one invocation.

    Args:
        backend: 'rclpy' or 'cyclonedds'.
        subscribe: Subscribe to the states and commands (a third reader of each, as a
            recorder would be); False: a node that only spins (the run unobserved).
    """

    def __init__(self, backend, subscribe=True):
        self.states, self.commands = set(), set()
        self.backend, self.subscribed = backend, subscribe
        if backend == 'rclpy':  # optional: only where the Jazzy wheels are installed
            import rclpy
            from rclpy.context import Context
            from rclpy.executors import SingleThreadedExecutor
            from sensor_msgs.msg import JointState

            self.context = Context()
            rclpy.init(context=self.context)
            self.node = rclpy.create_node('latency_bench', context=self.context)
            self.executor = SingleThreadedExecutor(context=self.context)
            self.executor.add_node(self.node)
        else:
            JointState = messages.JointState  # the class, as in the rclpy branch
            self.context = dds.Context(['latency_bench'])
            self.node = dds.Node('latency_bench', context=self.context)
            self.executor = self.context.executor((self.node,))
        self.subs = [] if not subscribe else [
            self.node.create_subscription(
                JointState, 'joint_states',
                lambda m: self.states.add(_stamp(m)), 100),
            self.node.create_subscription(
                JointState, 'command/joint_position',
                lambda m: self.commands.add(_stamp(m)), 100)]

    def spin(self, seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=min(0.1, max(0.0, end - time.monotonic())))

    def close(self):
        if self.backend == 'rclpy':
            self.node.destroy_node()
            self.context.try_shutdown()
        else:
            self.context.shutdown()


#: ways of serving the SPG's joint states on rclpy: (hot_path parameter, extra environment)
SPG_PATHS = {'wait_set': ('wait_set', {}), 'executor': ('executor', {}),
             'events': ('executor', {'IFC_SPG_RCLPY_EXECUTOR': 'events'})}


def baseline(rate=500.0, seconds=10.0, clock=time.perf_counter):
    """The machine's own pacing: a plain Python loop at ``rate`` [Hz] for ``seconds`` [s].

    Absolute deadlines t_k = t_0 + k/rate, ``time.sleep`` until each (no busy wait, nothing
    else done). A wake-up later than the next deadline misses the periods it slept through;
    the loop then resumes at the first deadline still ahead.

    Returns:
        ``{'rate', 'seconds', 'periods', 'overshoot_us': {p50, p99, max}, 'missed',
        'missed_pct'}``: overshoot of each wake-up past its deadline [µs], missed periods
        (of ``seconds * rate``).
    """
    period = 1.0 / rate
    n = round(seconds * rate)
    late, missed, k = [], 0, 0
    t0 = clock() + period
    while k < n:
        deadline = t0 + k * period
        remaining = deadline - clock()
        if remaining > 0:
            time.sleep(remaining)
        over = clock() - deadline
        late.append(over)
        skipped = int(over // period)  # deadlines passed while asleep
        missed += skipped
        k += 1 + skipped
    lat = sorted(late)
    pick = lambda q: lat[min(len(lat) - 1, int(q * len(lat)))] * 1e6  # noqa: E731
    return {'rate': rate, 'seconds': seconds, 'periods': n,
            'overshoot_us': {'p50': pick(0.5), 'p99': pick(0.99), 'max': lat[-1] * 1e6},
            'missed': missed, 'missed_pct': 100.0 * missed / n}


def run(seconds=60.0, stream=sys.stderr, bridge_backend=None, spg_backend=None, rate=500.0,
        spg_path='wait_set', bridge_path='wait_set', listen=False):
    """Run the bridge and the SPG for ``seconds`` [s] of realtime; return the results dict.

    Args:
        seconds: realtime duration [s].
        stream: progress output.
        bridge_backend: 'rclpy' or 'cyclonedds' for the bridge process; None: the backend
            of this process (``ifc_spg.ros.BACKEND``).
        spg_backend: The same for the SPG process (and this process' listener).
        rate: The bridge's rate [Hz] (the SPG's dt is 1 / rate).
        spg_path: How an SPG on rclpy serves its joint states, a key of :data:`SPG_PATHS`
            (ignored on the built-in backend).
        bridge_path: How a bridge on rclpy serves its commands: its ``hot_path`` parameter,
            'wait_set' or 'executor' (ignored on the built-in backend).
        listen: This process subscribes to the states and commands too (a third process
            reading both topics, as a recorder; it costs the SPG a second command reader and
            the machine the listener's CPU).
    """
    bridge_backend = bridge_backend or ros.BACKEND
    spg_backend = spg_backend or ros.BACKEND
    domain = random_domain_id()
    envs = {b: loopback_env(domain, backend=b) for b in {bridge_backend, spg_backend}}
    hot_path, extra = SPG_PATHS[spg_path] if spg_backend == 'rclpy' else ('wait_set', {})
    bridge_path = bridge_path if bridge_backend == 'rclpy' else 'wait_set'
    spg_env = {**envs[spg_backend], **extra}
    saved = {k: os.environ.get(k) for k in envs[spg_backend] if k not in os.environ or
             os.environ[k] != envs[spg_backend][k]}
    os.environ.update(envs[spg_backend])  # the listener's domain and loopback settings
    tmp = Path(tempfile.mkdtemp(prefix='latency_bench.'))
    (tmp / 'reach.yaml').write_text(STACK)
    listener = _Listener(spg_backend, subscribe=listen)
    try:
        _run_processes(listener, tmp, envs, spg_env, seconds, stream, bridge_backend,
                       spg_backend, rate, hot_path, bridge_path)
    finally:
        listener.close()
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
    res = _results(listener, tmp, seconds, bridge_backend, spg_backend, rate)
    res['spg_path'] = spg_path if spg_backend == 'rclpy' else 'built-in'
    res['bridge_path'] = bridge_path if bridge_backend == 'rclpy' else 'built-in'
    res['listener'] = listen
    return res


def _run_processes(listener, tmp, envs, spg_env, seconds, stream, bridge_backend, spg_backend,
                   rate, hot_path, bridge_path):
    """Start the SPG, then the bridge for ``seconds``; listen until the bridge ends."""
    bindir = Path(sys.executable).parent
    procs, logs = [], []

    def start(name, env, *args):
        logs.append(open(tmp / f'{name}.log', 'w+'))
        procs.append(subprocess.Popen([str(bindir / name), *args], env=env,
                                      stdout=logs[-1], stderr=subprocess.STDOUT))
        return procs[-1]

    try:
        spg = start('spg_node', spg_env, '--ros-args', '--params-file',
                    str(find_config_dir() / 'lbr_iiwa14.yaml'), '-p',
                    f"task_stack_file:={tmp / 'reach.yaml'}", '-p', f'dt:={1.0 / rate!r}',
                    '-p', f'hot_path:={hot_path}')
        deadline = time.monotonic() + 60.0  # let the SPG start (imports) before the clock
        while time.monotonic() < deadline and spg.poll() is None and \
                'waiting for' not in (tmp / 'spg_node.log').read_text():
            listener.spin(0.1)
        listener.spin(0.5)
        bridge = start('sim_bridge', envs[bridge_backend], '--ros-args', '-p',
                       'robot:=lbr_iiwa14', '-p', 'scene:=free', '-p', 'mode:=realtime', '-p',
                       f'rate:={float(rate)!r}', '-p', f'duration:={seconds}', '-p',
                       f'hot_path:={bridge_path}')
        print(f'latency_bench: realtime run of {seconds:g} s at {rate:g} Hz, bridge on '
              f'{bridge_backend} (hot_path {bridge_path}), SPG on {spg_backend} (hot_path '
              f'{hot_path}'
              f"{', EventsExecutor' if 'IFC_SPG_RCLPY_EXECUTOR' in spg_env else ''}; logs in "
              f'{tmp})', file=stream, flush=True)
        cpu0 = _cpu_seconds(spg.pid)
        while bridge.poll() is None:
            listener.spin(0.2)
        listener.spin(0.5)
        cpu1 = _cpu_seconds(spg.pid)
        if cpu0 is not None and cpu1 is not None:
            (tmp / 'spg_cpu').write_text(repr(cpu1 - cpu0))
        stop_process(spg)
    finally:
        for proc in procs:
            stop_process(proc)
        for f in logs:
            f.close()


def _cpu_seconds(pid):
    """User + system CPU time [s] of process ``pid`` so far (Linux /proc; None elsewhere)."""
    try:
        fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def _results(listener, tmp, seconds, bridge_backend, spg_backend, rate):
    """The results dict of one pairing, from the listener and the bridge's exit lines."""
    bridge_log = (tmp / 'sim_bridge.log').read_text()
    ticks = re.search(r'spg_node: (\d+) ticks', (tmp / 'spg_node.log').read_text())
    cpu = tmp / 'spg_cpu'
    cpu_per_tick = (1e6 * float(cpu.read_text()) / int(ticks.group(1))
                    if cpu.exists() and ticks and int(ticks.group(1)) else None)
    pacing = re.search(r'p50 lateness (\d+) us, p99 (\d+) us, (\d+) overrun\(s\), (\d+) missed',
                       bridge_log)
    measured = re.search(r'command latency p50 ([\d.]+) ms, p99 ([\d.]+) ms, max ([\d.]+) ms',
                         bridge_log)
    return {
        'bridge_backend': bridge_backend,
        'spg_backend': spg_backend,
        'seconds': seconds,
        'rate': rate,
        'states': len(listener.states) if listener.subscribed else None,
        'commands': len(listener.commands) if listener.subscribed else None,
        'expected_ticks': round(seconds * rate),
        'missed_here': len(listener.states - listener.commands) if listener.subscribed
        else None,
        # the bridge's own clock: its state published -> the command answering it received
        'latency_ms': dict(zip(('p50', 'p99', 'max'), map(float, measured.groups())))
        if measured else None,
        'bridge_missed_commands': int(pacing.group(4)) if pacing else None,
        'bridge_pacing_us': {'p50': int(pacing.group(1)), 'p99': int(pacing.group(2)),
                             'overruns': int(pacing.group(3))} if pacing else None,
        # the SPG process' CPU time (all threads: tick, DDS, timers) over the bridge's run
        'spg_cpu_us_per_tick': cpu_per_tick,
        'logs': str(tmp),
    }


PAIRS = {'all': [('rclpy', 'rclpy'), ('cyclonedds', 'cyclonedds'), ('rclpy', 'cyclonedds'),
                 ('cyclonedds', 'rclpy')],
         'same': [('rclpy', 'rclpy'), ('cyclonedds', 'cyclonedds')]}


def _pairs(text, have_rclpy):
    if text in PAIRS:
        pairs = PAIRS[text]
    else:
        pairs = []
        for item in text.split(','):
            bridge, _, spg = item.partition(':')
            if bridge not in ('rclpy', 'cyclonedds') or spg not in ('rclpy', 'cyclonedds'):
                raise SystemExit(f"--pairs: '{item}' is not BRIDGE:SPG with each rclpy or "
                                 "cyclonedds (or use 'all', 'same')")
            pairs.append((bridge, spg))
    if not have_rclpy:
        dropped = [p for p in pairs if 'rclpy' in p]
        if dropped:
            print('latency_bench: rclpy is not installed; running only the built-in backend '
                  'pairing', file=sys.stderr)
        pairs = [p for p in pairs if 'rclpy' not in p] or [('cyclonedds', 'cyclonedds')]
    return pairs


def _list(text, name, choices=None, kind=str):
    items = [kind(x) for x in text.split(',') if x]
    bad = [x for x in items if choices is not None and x not in choices]
    if bad or not items:
        raise SystemExit(f"{name}: '{text}' is not a list of {', '.join(choices or ['values'])}")
    return items


def _ratio(value, base):
    return f'{value / base:7.1f}' if base else '      -'


def main(argv=None):
    """``python -m benchmarks.latency_bench``; exit 1 if a pairing measured nothing."""
    parser = argparse.ArgumentParser(prog='python -m benchmarks.latency_bench',
                                     description=__doc__.split('\n')[0])
    parser.add_argument('--seconds', type=float, default=60.0, help='realtime run [s]')
    parser.add_argument('--rate', default='500',
                        help='bridge rate(s) [Hz], a list: 500, 1000 or 500,1000 (default 500)')
    parser.add_argument('--pairs', default='all',
                        help="'all' (default: rclpy-rclpy, built-in-built-in and both mixed), "
                             "'same', or a list BRIDGE:SPG,... of rclpy / cyclonedds")
    parser.add_argument('--spg-paths', default='wait_set',
                        help='with the SPG on rclpy, one run per way of serving its joint '
                             f"states, a list of {', '.join(SPG_PATHS)} (default wait_set, "
                             "the node's default)")
    parser.add_argument('--bridge-paths', default='wait_set',
                        help='with the bridge on rclpy, one run per way of serving its commands, '
                             "a list of wait_set, executor (its hot_path parameter; default "
                             "wait_set, the node's default)")
    parser.add_argument('--baseline-seconds', type=float, default=None,
                        help='length of the machine baseline per rate [s] (default --seconds; '
                             '0: none)')
    parser.add_argument('--nice', type=int, default=None,
                        help='run this process (the baseline, the listener) and the bridge and '
                             'SPG at this nice value, e.g. -10 as the tests and a robot PC do '
                             '(needs root or CAP_SYS_NICE; default: as started)')
    parser.add_argument('--fifo', type=int, default=None,
                        help='run this process (the baseline, the listener) and the bridge and '
                             'SPG under SCHED_FIFO at this priority (1-99), as `chrt -f PRIO '
                             'ros2 run ...` on a robot PC (needs root or CAP_SYS_NICE; default: '
                             'as started)')
    parser.add_argument('--listener', default='off',
                        help="'off' (default: bridge and SPG alone), 'on' (this process also "
                             "subscribes to the states and commands, as a recorder would) or "
                             "'both' (each run twice, without and with)")
    parser.add_argument('--json', action='store_true', help='print the results as JSON')
    opts = parser.parse_args(sys.argv[1:] if argv is None else argv)
    if opts.nice is not None:
        os.setpriority(os.PRIO_PROCESS, 0, opts.nice)  # inherited by the bridge and the SPG
    if opts.fifo is not None:  # inherited by the bridge and the SPG, all their threads
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(opts.fifo))
        except (OSError, ValueError) as exc:
            parser.error(f'--fifo {opts.fifo}: {exc} (a priority 1-99; root or CAP_SYS_NICE)')
    rates = _list(opts.rate, '--rate', kind=float)
    paths = _list(opts.spg_paths, '--spg-paths', SPG_PATHS)
    bridge_paths = _list(opts.bridge_paths, '--bridge-paths', ros.HOT_PATHS)
    listens = {'off': [False], 'on': [True], 'both': [False, True]}.get(opts.listener)
    if listens is None:
        parser.error(f"--listener: '{opts.listener}' is not off, on or both")
    try:
        import rclpy  # noqa: F401 -- optional: is it installed?
        have_rclpy = True
    except ImportError:
        have_rclpy = False
    results, baselines = [], {}
    for rate in rates:
        base_seconds = opts.seconds if opts.baseline_seconds is None else opts.baseline_seconds
        if base_seconds > 0:
            print(f'latency_bench: machine baseline, a sleep loop at {rate:g} Hz for '
                  f'{base_seconds:g} s', file=sys.stderr, flush=True)
            baselines[rate] = baseline(rate, base_seconds)
        results += [run(opts.seconds, bridge_backend=b, spg_backend=s, rate=rate, spg_path=path,
                        bridge_path=bridge_path, listen=listen)
                    for b, s, bridge_path, path, listen in _runs(
                        _pairs(opts.pairs, have_rclpy), bridge_paths, paths, listens)]
    if opts.json:
        print(json.dumps({'load_average': os.getloadavg(), 'nice': os.getpriority(
            os.PRIO_PROCESS, 0), 'fifo': _fifo_priority(), 'baselines': list(baselines.values()),
            'runs': results},
                         indent=1))
    else:
        _print_table(results, baselines)
    return 0 if all(res['latency_ms'] for res in results) else 1


def _fifo_priority():
    """This process' SCHED_FIFO priority, or None under another policy."""
    if os.sched_getscheduler(0) != os.SCHED_FIFO:
        return None
    return os.sched_getparam(0).sched_priority


def _runs(pairs, bridge_paths, spg_paths, listens):
    """(bridge backend, SPG backend, bridge path, SPG path, listen) of each run, in order."""
    return [(b, s, bridge_path, path, listen) for b, s in pairs
            for bridge_path in (bridge_paths if b == 'rclpy' else ['wait_set'])
            for path in (spg_paths if s == 'rclpy' else ['wait_set'])
            for listen in listens]


def _print_table(results, baselines):
    """One line per rate's baseline and per run; x base: the run's value over the baseline's."""
    nan = float('nan')
    load = os.getloadavg()
    fifo = _fifo_priority()
    print(f'load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}, nice '
          f"{os.getpriority(os.PRIO_PROCESS, 0)}{'' if fifo is None else f', SCHED_FIFO {fifo}'}")
    print('rate  bridge      path       spg         path       listener  p50 ms  p99 ms  max ms  '
          'missed  missed %  x base  p99 x base  SPG CPU us/tick')
    for rate, base in baselines.items():
        over = base['overshoot_us']
        label = f"baseline: sleep loop, {base['periods']} periods"
        print(f"{rate:>4g}  {label:<54}"
              f"{over['p50'] / 1e3:>7.3f} {over['p99'] / 1e3:>7.3f} {over['max'] / 1e3:>7.3f} "
              f"{base['missed']:>7} {base['missed_pct']:>9.3f}")
    for res in results:
        lat = res['latency_ms'] or {'p50': nan, 'p99': nan, 'max': nan}
        missed = res['bridge_missed_commands']
        share = 100.0 * missed / res['expected_ticks'] if missed is not None else nan
        base = baselines.get(res['rate'])
        ratios = (_ratio(share, base['missed_pct']) + '  ' +
                  _ratio(lat['p99'] * 1e3, base['overshoot_us']['p99'])) if base else ''
        print(f"{res['rate']:>4g}  {res['bridge_backend']:<11} {res['bridge_path']:<10} "
              f"{res['spg_backend']:<11} "
              f"{res['spg_path']:<9} {'on' if res['listener'] else 'off':>8} "
              f"{lat['p50']:>7.3f} {lat['p99']:>7.3f} "
              f"{lat['max']:>7.3f} {missed if missed is not None else '?':>7} {share:>9.3f} "
              f"{ratios or ' ' * 17}  {res['spg_cpu_us_per_tick'] or nan:>10.0f}")


if __name__ == '__main__':
    sys.exit(main())
