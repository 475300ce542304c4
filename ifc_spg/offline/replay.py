"""Recompute the SPG output from a bag and compare it with the recorded commands.

    ifc-spg replay BAG [--tolerance 1e-9] [--robot NAME] [--json]

A live bag (``ifc-spg bag record`` or ``ros2 bag record`` of the product topics, started at
any time) holds the SPG's latched ``spg/config`` and its per-tick ``spg/state``: the replay
starts from the first recorded state, with that configuration and running stack (its
``init`` values captured where the live run captured them, the cascade warm-started from the
working sets the live one had), and recomputes every later q_v exactly (max |dq_v| 0 in the
tests; bags recorded before ``spg/state`` carried the working sets start cold, which the
default tolerance of 1e-9 rad does not always cover on a stalled stack). Joint states
recorded before it and states whose command the recorder stopped before receiving are the
recording's edges and do not fail the replay.
Joint states the recorder missed mid-run (a reliable KEEP_LAST writer drops a sample a slow
reader missed once its history is full) show in ``spg/state``'s tick count: the replay
resynchronises from the recorded state after them and reports them (``lost``), with the
commands it could not compare (``unverified``). Joint states the live SPG itself never
ticked on (a realtime bridge outpacing a loaded SPG: its subscription's queue drops the
oldest) show there too, as recorded states between two consecutive ticks' stamps: the
replay does not tick on them either (``not_ticked``); where ``spg/state`` samples are
missing too, a recorded state showing fewer ticks than the replay ran resynchronises.

Otherwise the replay starts from the first tick. The SPG configuration comes from the bag
(metadata ``custom_data['ifc_spg.node.config']``, else ``spg/config``, else the first
``spg/status`` message carrying ``config``; ``--robot`` is the last resort,
with default parameters), and so do the robot's IFC gains K, D the run used (a scenario's
``sim: {stiffness, damping}``): ``custom_data['ifc_spg.robot_params']``, else ``robot_params``
in ``spg/status``. A bag without them (recorded before they were stored) is replayed with
the robot's default K, D and a warning; recorded limits that differ from the current robot
model are warned about too. Every ``joint_states`` message is one tick, in stamp order, fed
to a fresh :class:`~ifc_spg.node.core.SpgRunner` exactly as the live node or the offline
runner did; each task stack on ``spg/task_stack`` is handed to it before the tick at which
the recorded run activated it (``stack.since`` in ``spg/status``; without it, the first
status showing the stack's id; without statuses, the message's log time). The recorded
watchdog timeout is kept (a stamp gap over it restarts from the measured q, as live), the
runner's clock is fixed, and each recorded ``watchdog`` status event (the live node's
wall-clock timer) marks the runner stale after the tick it reports, so a restarted bridge
(stamps from 0 again) is replayed as the restart it was. The result is
max |Δq_v| over all ticks and joints between recomputed and recorded
``command/joint_position`` (matched by header stamp). Exit status 0 when it is within the
tolerance, 1 when it is not (or commands are missing), 2 on an unreadable bag.
"""

import bisect
import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np

from ifc_spg.errors import IfcSpgError, ParameterError
from ifc_spg.model import RobotModel
from ifc_spg.node.config import SpgConfig
from ifc_spg.node.core import SpgRunner, parse_task_stack, robot_params
from ifc_spg.offline.bag import BagReader, stamp_ns
from ifc_spg.offline.runner import CONFIG_KEY, ROBOT_PARAMS_KEY
from ifc_spg.ros.stamps import join_ns

__all__ = ['ReplayResult', 'read_robot_params', 'read_spg_config', 'replay',
           'replay_robot']


@dataclasses.dataclass
class ReplayResult:
    """Outcome of :func:`replay`.

    Attributes:
        max_abs_diff: max |Δq_v| over ticks and joints in [rad] (inf if nothing matched).
        worst_stamp: Stamp [s] of the worst tick (None if none matched).
        worst_joint: Joint name of the worst difference.
        ticks: Joint states replayed.
        compared: Ticks with a recorded command compared.
        missing: Ticks without a recorded command (or without a recomputed one).
        stacks: Task stacks handed to the SPG.
        config: The SPG configuration used (dict).
        robot_params: The robot parameters used (dict of
            :func:`~ifc_spg.node.core.robot_params`: K, D, limits).
        gains_recorded: True when K, D came from the bag, False for the defaults.
        warnings: What the replay could not take from the bag (messages).
        skipped: Recorded joint states before the first recorded SPG state (a bag recorded
            mid-run): not replayed.
        unanswered: Joint states after the last recorded command (the recorder stopped
            first): replayed, not compared, not a failure.
        resumed: True when the replay started from a recorded ``spg/state``.
        lost: Ticks the live SPG ran (its recorded ``spg/state`` counts them) whose joint
            state the bag lacks: the recorder missed them (Fast DDS' reliable KEEP_LAST
            writers drop samples a slow reader missed once newer ones fill the history).
        resyncs: Times the replay resynchronised from a recorded ``spg/state`` after lost
            ticks (that needs ``spg/config`` in the bag too).
        unverified: Ticks not compared: computed across lost ticks before a
            resynchronisation, or whose command the bag lacks although ``spg/state`` shows
            the live SPG ran them.
        not_ticked: Recorded joint states the live SPG did not tick on (its ``spg/state``
            shows two consecutive ticks at the stamps around them: its subscription dropped
            them while it was busy): not replayed.
    """

    max_abs_diff: float
    worst_stamp: float | None
    worst_joint: str
    ticks: int
    compared: int
    missing: int
    stacks: int
    config: dict[str, Any]  # JSON document
    robot_params: dict[str, Any] | None = None  # JSON document
    gains_recorded: bool = False
    warnings: list[str] = dataclasses.field(default_factory=list)
    skipped: int = 0
    unanswered: int = 0
    resumed: bool = False
    lost: int = 0
    resyncs: int = 0
    unverified: int = 0
    not_ticked: int = 0


def read_spg_config(bag, statuses, robot=None, configs=()):
    """The :class:`~ifc_spg.node.config.SpgConfig` a bag was recorded with.

    Args:
        bag: The :class:`~ifc_spg.offline.bag.BagReader`.
        statuses: The recorded ``spg/status`` documents, ``[(log time, dict)]``.
        robot: Robot name to use (None: the recorded one).
        configs: The recorded ``spg/config`` documents, ``[(log time, dict)]``.

    Raises:
        ParameterError: The bag holds no configuration and no ``robot`` is given.
    """
    doc = None
    if CONFIG_KEY in bag.custom_data:
        doc = json.loads(bag.custom_data[CONFIG_KEY])
    else:
        doc = next((s['config'] for _, s in list(configs) + list(statuses)
                    if isinstance(s.get('config'), dict)), None)
    if doc is None:
        if robot is None:
            raise ParameterError(f"bag '{bag.path}' holds no SPG configuration (no custom_data "
                                 f"'{CONFIG_KEY}', no spg/config, no spg/status with 'config');"
                                 ' pass --robot NAME to replay with default parameters')
        return SpgConfig(robot=robot)
    known = {f.name for f in dataclasses.fields(SpgConfig)}
    doc = {k: v for k, v in doc.items() if k in known}
    if robot is not None:
        doc['robot'] = robot
    # the recorded watchdog timeout is kept: the stamp-gap restart rule depends on it (the
    # wall-clock trips are replayed from the recorded 'watchdog' events, see replay())
    return SpgConfig(**doc)


def read_robot_params(bag, statuses, configs=()):
    """The robot-parameter record of a bag (dict), or None for bags without one.

    Args:
        bag: The :class:`~ifc_spg.offline.bag.BagReader`.
        statuses: The recorded ``spg/status`` documents, ``[(log time, dict)]``.
        configs: The recorded ``spg/config`` documents, ``[(log time, dict)]``.

    Raises:
        ParameterError: The metadata's record is not a JSON object.
    """
    if ROBOT_PARAMS_KEY in bag.custom_data:
        try:
            doc = json.loads(bag.custom_data[ROBOT_PARAMS_KEY])
        except json.JSONDecodeError as exc:
            raise ParameterError(f"bag '{bag.path}': custom_data '{ROBOT_PARAMS_KEY}' is not "
                                 f'JSON ({exc})') from None
        if not isinstance(doc, dict):
            raise ParameterError(f"bag '{bag.path}': custom_data '{ROBOT_PARAMS_KEY}' must be a "
                                 f'JSON object, got {type(doc).__name__}')
        return doc
    return next((s['robot_params'] for _, s in list(configs) + list(statuses)
                 if isinstance(s, dict) and isinstance(s.get('robot_params'), dict)), None)


_CHECKED = ('tau_max', 'v_max', 'a_max', 'q_min', 'q_max')


def replay_robot(config, doc, where='bag'):
    """The robot to replay with: ``config.robot`` with the recorded K, D of ``doc``.

    Args:
        config: The :class:`~ifc_spg.node.config.SpgConfig` to replay with.
        doc: The bag's robot-parameter record (:func:`read_robot_params`), or None.
        where: Name of the bag for messages.

    Returns:
        ``(robot, gains_recorded, warnings)``.

    Raises:
        ParameterError: A record whose K or D is not a valid per-joint vector.
    """
    robot = RobotModel.from_config(config.robot)
    if doc is None:
        return robot, False, [
            f"{where} holds no robot parameters (no custom_data '{ROBOT_PARAMS_KEY}', no "
            "spg/status with 'robot_params'; bags recorded before they were stored): "
            f"replaying with the default K, D of '{robot.name}'. A run whose scenario "
            'overrode sim.stiffness/sim.damping will not reproduce']
    warnings = []
    recorded = doc.get('robot')
    if recorded is not None and recorded != robot.name:
        return robot, False, [
            f"{where} was recorded with robot '{recorded}', replaying as '{robot.name}' "
            f'(--robot): its recorded K, D do not apply; using the defaults of '
            f"'{robot.name}'"]
    names = doc.get('joint_names')
    if names is not None and list(names) != list(robot.joint_names):
        raise ParameterError(f"{where}: custom_data '{ROBOT_PARAMS_KEY}' lists joints "
                             f"{names} but robot '{robot.name}' has "
                             f'{list(robot.joint_names)}; replay with --robot NAME of the '
                             'recording robot')
    for key in ('stiffness', 'damping'):
        value = doc.get(key)
        if not isinstance(value, list) or len(value) != robot.n:
            raise ParameterError(f"{where}: custom_data '{ROBOT_PARAMS_KEY}' field '{key}' "
                                 f"must list {robot.n} values (one per joint of "
                                 f"'{robot.name}'), got {value!r}")
    robot = robot.with_gains(stiffness=doc['stiffness'], damping=doc['damping'],
                             where=f"{where}: custom_data '{ROBOT_PARAMS_KEY}' field ")
    for key in _CHECKED:
        value = doc.get(key)
        current = getattr(robot, key)
        if value is not None and (len(value) != robot.n or
                                  not np.array_equal(np.asarray(value, dtype=float), current)):
            warnings.append(f"{where} recorded {key} = {value} but robot '{robot.name}' now "
                            f'has {current.tolist()} (the model changed since the recording); '
                            'replaying with the current values')
    stiff = [j for j, s in zip(robot.joint_names, robot.stiff_mask) if s]
    if doc.get('stiff_joints') is not None and list(doc['stiff_joints']) != stiff:
        warnings.append(f"{where} recorded stiff_joints = {doc['stiff_joints']} but robot "
                        f"'{robot.name}' now has {stiff} (the model changed since the "
                        'recording); replaying with the current ones')
    return robot, True, warnings


def _activation_times(stack_msgs, statuses, accepted):
    """Stamp [s] before whose tick each stack message is handed to the SPG (None: never)."""
    since: dict[int, float] = {}
    first_seen: dict[int, float] = {}
    for _, doc in statuses:
        st = doc.get('stack') if isinstance(doc, dict) else None
        if not st or not st.get('id'):
            continue
        sid = int(st['id'])
        if st.get('since') is not None:
            since.setdefault(sid, float(st['since']))
        if doc.get('stamp') is not None:
            first_seen.setdefault(sid, float(doc['stamp']))
    out: list[float | None] = []
    next_id = 0
    ids: list[int | None] = []
    for ok in accepted:
        if ok:
            next_id += 1
            ids.append(next_id)
        else:
            ids.append(None)
    known = {**first_seen, **since}
    for i, (t_log, _) in enumerate(stack_msgs):
        stack_id = ids[i]
        if known:
            if stack_id is None:
                out.append(None)  # rejected: no effect on q_v
                continue
            # a stack overridden before it ran has no status: hand it over with the next one
            later = [known[j] for j in range(stack_id, next_id + 1) if j in known]
            out.append(later[0] if later else None)
        else:
            out.append(t_log * 1e-9)
    return out


def _snapshot_stamp(vec):
    """The stamp [ns] of the tick a recorded ``spg/state`` vector follows."""
    return join_ns(vec[1], vec[2])


def _resume_point(snapshots, state_stamps):
    """The recorded ``spg/state`` to start from.

    That is the earliest tick j whose successor j+1 has a snapshot too, stamped like a
    recorded joint state (so no tick between them is lost).

    Returns:
        The snapshot vector of tick j, or None.
    """
    by_tick: dict[int, np.ndarray] = {}
    for vec in snapshots:
        by_tick.setdefault(int(vec[0]), vec)
    for tick in sorted(by_tick):
        nxt = by_tick.get(tick + 1)
        if nxt is not None and _snapshot_stamp(nxt) in state_stamps:
            return by_tick[tick]
    return None


def _config_at(configs, stamp_s):
    """The ``spg/config`` document in force after the tick at ``stamp_s`` [s].

    That is the one whose stack's latest activation is the newest not after it (None: no
    document).
    """
    best, best_t = None, None
    for _, doc in configs:
        stack = doc.get('stack')
        t = stack['activations'][-1]['t'] if stack and stack.get('activations') else -np.inf
        if t <= stamp_s + 1e-10 and (best_t is None or t >= best_t):
            best, best_t = doc, t
    return best


@dataclasses.dataclass
class _Recorded:
    """What a bag holds for the replay, topic by topic."""

    states: list = dataclasses.field(default_factory=list)      # (stamp [ns], JointState)
    commands: dict = dataclasses.field(default_factory=dict)    # stamp [ns] -> JointState
    stack_msgs: list = dataclasses.field(default_factory=list)  # (log time [ns], text)
    statuses: list = dataclasses.field(default_factory=list)    # (log time [ns], doc)
    configs: list = dataclasses.field(default_factory=list)     # (log time [ns], doc)
    snapshots: list = dataclasses.field(default_factory=list)   # spg/state vectors

    def add(self, name, t_log, msg):
        """File one message of topic ``name`` (relative) logged at ``t_log`` [ns]."""
        if name == 'joint_states':
            self.states.append((stamp_ns(msg.header.stamp), msg))
        elif name == 'command/joint_position':
            self.commands.setdefault(stamp_ns(msg.header.stamp), msg)
        elif name == 'spg/task_stack':
            self.stack_msgs.append((t_log, msg.data))
        elif name == 'spg/state':
            self.snapshots.append(np.asarray(msg.data, dtype=float))
        else:
            try:
                doc = json.loads(msg.data)
            except json.JSONDecodeError:
                return
            if isinstance(doc, dict):
                (self.configs if name == 'spg/config' else self.statuses).append((t_log, doc))


def _read_bag(path, robot):
    """``(recorded, config, model, gains_recorded, warnings)`` of the bag at ``path``."""
    with BagReader(path) as bag:
        topics = {t.lstrip('/'): t for t in bag.topics}
        for need in ('joint_states', 'command/joint_position'):
            if need not in topics:
                raise ParameterError(f"bag '{path}' has no '{need}' topic; topics: "
                                     f"{', '.join(sorted(bag.topics)) or 'none'}")
        rec = _Recorded()
        wanted = {topics[k] for k in ('joint_states', 'command/joint_position', 'spg/task_stack',
                                      'spg/status', 'spg/config', 'spg/state') if k in topics}
        for topic, t_log, msg in bag.messages(wanted):
            rec.add(topic.lstrip('/'), t_log, msg)
        config = read_spg_config(bag, rec.statuses, robot, rec.configs)
        model, gains_recorded, warnings = replay_robot(
            config, read_robot_params(bag, rec.statuses, rec.configs), where=f"bag '{bag.path}'")
    rec.states.sort(key=lambda x: x[0])
    return rec, config, model, gains_recorded, warnings


def _watchdog_trips(statuses):
    """Tick counts of the recorded ``watchdog`` status events (the live node's timer trips)."""
    return sorted({int(doc['tick']) for _, doc in statuses
                   if isinstance(doc, dict) and isinstance(doc.get('event'), dict)
                   and doc['event'].get('type') == 'watchdog'
                   and isinstance(doc.get('tick'), int)})


@dataclasses.dataclass
class _Plan:
    """Where the replay starts and what it hands to the SPG on the way."""

    stack_msgs: list        # (when, text) of the stacks to hand over
    pending: list           # sorted (when [s], index into stack_msgs)
    trips: list             # tick counts after which the runner is marked stale
    after: int | None = None  # stamp [ns] of the restored state (None: from the first tick)


def _resume_plan(spg, rec, start, trips, path):
    """Restore ``spg`` from the recorded state ``start``; later stacks from spg/config."""
    start_s = _snapshot_stamp(start) * 1e-9
    doc = _config_at(rec.configs, start_s)
    if doc is None:
        raise ParameterError(f"bag '{path}' has spg/state but no spg/config in force at "
                             f'{start_s:.3f} s; record spg/config (latched) too')
    after = spg.restore(start, doc)
    running = (doc.get('stack') or {}).get('id')
    # later stacks, from the spg/config documents: each at its first tick
    stack_msgs, seen_ids = [], {running}
    for _, later in rec.configs:
        st = later.get('stack')
        if st and st.get('id') not in seen_ids and st.get('since') is not None and \
                st['since'] > start_s:
            seen_ids.add(st['id'])
            stack_msgs.append((st['since'], st['text']))
    pending = sorted((w, i) for i, (w, _) in enumerate(stack_msgs))
    return _Plan(stack_msgs, pending, [t for t in trips if t > spg.ticks], after)


def _first_tick_plan(spg, rec, trips):
    """From the first tick: each recorded stack at the tick the recorded run activated it."""
    accepted = []
    for _, text in rec.stack_msgs:
        try:
            parse_task_stack(text).build(spg.robot)
            accepted.append(True)
        except IfcSpgError:
            accepted.append(False)
    when = _activation_times(rec.stack_msgs, rec.statuses, accepted)
    pending = sorted(((w, i) for i, w in enumerate(when) if w is not None))
    return _Plan(rec.stack_msgs, pending, trips)


class _Tally:
    """The comparison of recomputed with recorded commands, tick by tick.

    A comparison is provisional until a recorded ``spg/state`` confirms that the live SPG
    ran the same ticks (its tick count equals the replay's); one showing more ticks means the
    bag lost joint states the live SPG used (a reliable KEEP_LAST writer drops samples a slow
    reader missed): the provisional comparisons since the last confirmation are dropped as
    unverified and the replay resynchronises from that recorded state.
    """

    def __init__(self, commands):
        self.commands = commands
        self.last_command = max(commands, default=None)
        self.worst, self.worst_stamp, self.worst_joint = 0.0, None, ''
        self.compared = self.missing = self.handed = self.skipped = self.unanswered = 0
        self.lost = self.resyncs = self.unverified = self.not_ticked = 0
        self.live_tick = None  # the tick count of the last recorded spg/state met
        self.seen = set()
        self._provisional = []  # (stamp [ns], |dq_v| max, joint) or (stamp, None, '')

    def compare(self, stamp, cmd, ticked=False):
        """Compare the recomputed ``cmd`` of the state at ``stamp`` [ns] with the recording.

        ``ticked``: a recorded ``spg/state`` shows the live SPG ran this tick, so a command
        the bag lacks is the recorder's loss (unverified), not a missing answer.
        """
        rec = self.commands.get(stamp)
        if rec is None and cmd is not None and (self.last_command is None or
                                                stamp > self.last_command):
            self.unanswered += 1  # the recorder stopped before this state's command arrived
            return
        if rec is None and ticked and cmd is not None:
            self.unverified += 1
            return
        if cmd is None or rec is None:
            self._provisional.append((stamp, None, ''))
            return
        recorded = np.array(_in_order(rec, cmd.names), dtype=float)
        diff = np.abs(cmd.position - recorded)
        j = int(np.argmax(diff)) if diff.size else 0
        d = float(diff[j]) if diff.size else 0.0
        if not np.all(np.isfinite(diff)):
            d = float('inf')
        self._provisional.append((stamp, d, cmd.names[j] if diff.size else ''))

    def confirm(self):
        """The live SPG ran the ticks compared so far: they count."""
        for stamp, d, joint in self._provisional:
            if d is None:
                self.missing += 1
                continue
            self.compared += 1
            if d > self.worst or self.worst_stamp is None:
                self.worst, self.worst_stamp, self.worst_joint = d, stamp * 1e-9, joint
        self._provisional.clear()

    def discard(self, lost):
        """The bag lost ``lost`` ticks: the comparisons since the last confirmation are void."""
        self.lost += lost
        self.resyncs += 1
        self.unverified += len(self._provisional)
        self._provisional.clear()


def _not_ticked(snapshots, stamps, commands):
    """Stamps [ns] of recorded joint states the live SPG did not tick on.

    Two consecutive recorded ``spg/state`` samples of ticks j and j + 1 (in the order they
    were recorded: a restarted SPG counts from 1 again) at stamps s_j < s_j+1: the live
    SPG ticked on no state stamped between them (its subscription dropped them, or it
    rejected them, which a replay would do too). Where samples are missing (the recorder
    missed them, or stopped taking them first), a state with neither an ``spg/state`` nor a
    command of its stamp, before the last recorded command, is taken as not ticked too; if
    the live SPG did tick on it, the next recorded state shows one tick more than the
    replay ran, and the replay resynchronises there.
    """
    if not snapshots:
        return set()
    stamps = sorted(stamps)
    out = set()
    for a, b in zip(snapshots, snapshots[1:]):
        lo, hi = _snapshot_stamp(a), _snapshot_stamp(b)
        if int(b[0]) == int(a[0]) + 1 and hi > lo:
            out.update(stamps[bisect.bisect_right(stamps, lo):bisect.bisect_left(stamps, hi)])
    last = max(commands, default=None)
    ticked = {_snapshot_stamp(vec) for vec in snapshots}
    out.update(s for s in stamps if last is not None and s < last and s not in commands and
               s not in ticked)
    return out


def _resync(spg, tally, plan, rec, stamp, snapshot):
    """Check the replay against the live ``snapshot`` (``spg/state`` of the tick at ``stamp``).

    Returns:
        A warning when the bag lost ticks and no ``spg/config`` allows resynchronising, else
        None.
    """
    live = int(snapshot[0])
    previous, tally.live_tick = tally.live_tick, live
    n = len(spg.joint_names)
    mine = spg.state_vector()
    # the replay ticked on states the live SPG did not (where the spg/state samples that
    # show it are missing too): the live count went on, by less than the replay's
    over = live < spg.ticks and previous is not None and previous < live
    if (live <= spg.ticks and not over) or not np.array_equal(mine[1:3 + n],
                                                              snapshot[1:3 + n]):
        # the same tick (or a restarted live SPG counting from 0 again, or a restarted
        # bridge's stamp the recorded state does not belong to: its measured q differs)
        tally.confirm()
        return None
    doc = _config_at(rec.configs, stamp * 1e-9)
    if doc is None:
        tally.confirm()
        return (f'the bag lacks {live - spg.ticks} tick(s) the live SPG ran before '
                f't = {stamp * 1e-9:.3f} s and has no spg/config to resynchronise from; later '
                'commands may differ')
    if over:
        tally.resyncs += 1
        tally.unverified += len(tally._provisional)
        tally._provisional.clear()
    else:
        tally.discard(live - spg.ticks)
    spg.restore(snapshot, doc)
    # the stacks and watchdog trips up to here are in the restored state already
    plan.pending[:] = [p for p in plan.pending if p[0] > stamp * 1e-9 + 1e-10]
    plan.trips[:] = [t for t in plan.trips if t > spg.ticks]
    return None


def _passed_over(stamp, tally, plan, not_ticked):
    """True (and counted) if the state at ``stamp`` [ns] is not one to replay."""
    if stamp in tally.seen:  # a lockstep bridge re-publishes a state it got no answer for
        return True
    tally.seen.add(stamp)
    if plan.after is not None and stamp <= plan.after:
        tally.skipped += 1  # before the first recorded SPG state: not reproducible
        return True
    if stamp in not_ticked:
        tally.not_ticked += 1  # the live SPG did not tick on it (spg/state shows it)
        return True
    return False


def _before_tick(spg, plan, tally, rec, stamp, snapshot):
    """Prepare the tick at ``stamp`` [ns] as the live SPG ran it.

    Hands over the stacks due; the streamed tasks use the references ``snapshot`` (the
    recorded ``spg/state`` of this tick, if any) shows the live SPG used.
    """
    pending = plan.pending
    while pending and pending[0][0] <= stamp * 1e-9 + 1e-10:
        _, i = pending.pop(0)
        spg.handle_task_stack(plan.stack_msgs[i][1])
        tally.handed += 1
    if snapshot is not None:
        doc = _config_at(rec.configs, stamp * 1e-9)
        if doc is not None:
            spg.replay_streams(snapshot, doc)


def _run_ticks(spg, states, plan, tally, rec):
    """Feed every recorded joint state (once per stamp) to ``spg``, as the live node did.

    Returns:
        Warnings (lost ticks the replay could not resynchronise after).
    """
    trips = plan.trips
    snapshots: dict[int, np.ndarray] = {}
    for vec in rec.snapshots:
        snapshots.setdefault(_snapshot_stamp(vec), vec)
    not_ticked = _not_ticked(rec.snapshots, [stamp for stamp, _ in states], rec.commands)
    warnings = []
    for stamp, msg in states:
        if _passed_over(stamp, tally, plan, not_ticked):
            continue
        _before_tick(spg, plan, tally, rec, stamp, snapshots.get(stamp))
        cmd = spg.handle_joint_state(msg.name, msg.position, msg.velocity, stamp)
        while trips and trips[0] <= spg.ticks:
            if trips.pop(0) == spg.ticks:
                spg.mark_stale('watchdog event recorded in the bag')
        tally.compare(stamp, cmd, stamp in snapshots)
        if stamp in snapshots:
            warning = _resync(spg, tally, plan, rec, stamp, snapshots[stamp])
            if warning:
                warnings.append(warning)
    tally.confirm()  # no recorded state says otherwise
    return warnings


def replay(path: str | Path, robot: str | None = None) -> ReplayResult:
    """Recompute the commands of a bag; returns a :class:`ReplayResult`.

    A bag with ``spg/state`` (a live run, recorded from any tick on) is replayed from the
    first recorded state the SPG published, with the configuration and running stack of
    ``spg/config``; later stacks are handed to it at the tick each became active. Recorded
    joint states before that point (``skipped``) and after the last recorded command
    (``unanswered``: the recorder stopped first) are the recording's edges, not failures.

    Args:
        path: Bag directory.
        robot: Robot name to replay as (the bag's, if None).

    Raises:
        ParameterError: The bag lacks the topics or the configuration a replay needs.
    """
    rec, config, model, gains_recorded, warnings = _read_bag(path, robot)
    # a fixed clock: the runner never trips by itself; the live node's timer trips are
    # replayed at the tick count their 'watchdog' status event recorded
    spg = SpgRunner(config, robot=model, clock=lambda: 0.0)
    trips = _watchdog_trips(rec.statuses)
    start = _resume_point(rec.snapshots, {stamp for stamp, _ in rec.states}) \
        if rec.snapshots else None
    plan = _first_tick_plan(spg, rec, trips) if start is None else \
        _resume_plan(spg, rec, start, trips, path)
    tally = _Tally(rec.commands)
    warnings += _run_ticks(spg, rec.states, plan, tally, rec)
    return ReplayResult(tally.worst if tally.compared else float('inf'), tally.worst_stamp,
                        tally.worst_joint, len(tally.seen) - tally.skipped - tally.not_ticked,
                        tally.compared,
                        tally.missing, tally.handed, dataclasses.asdict(config),
                        robot_params(model), gains_recorded, warnings, tally.skipped,
                        tally.unanswered, start is not None, tally.lost, tally.resyncs,
                        tally.unverified, tally.not_ticked)


def _in_order(msg, names):
    if not msg.name:
        return list(msg.position)
    index = {n: i for i, n in enumerate(msg.name)}
    return [msg.position[index[n]] if n in index else np.nan for n in names]
