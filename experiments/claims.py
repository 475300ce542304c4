"""The pass rules of the reproduction: one row per thesis claim, fixed before the runs.

Each :class:`Claim` names the thesis statement and where it is printed (table, figure,
section), the thesis value (most Ch. 3/4 experiments are plots without numbers: then the
statement is the value), our metric, the rule (``op`` and ``bound``) and, in ``history``,
every change of a setup or threshold made after a result had been seen, with the reason.
The harness (:mod:`experiments.reproduce`) evaluates the rules on the numbers of each run
and prints per claim: thesis value, ours, rule, verdict. An experiment is reproduced when
all of its claims pass. Nothing here is tuned to a run: a rule that fails, fails.

Version 11 (issue 29), after the v10 result had been seen: Fig. 5.12's two rules read the
static erroneous force ||f_s perp|| (K (q_v - q) through J^-T) instead of the measured one: the
sentence they judge says "applied erroneous forces", and Sec. 5.4.3 calls the red curve of its
graphs "the applied erroneous static forces" beside "the measured erroneous interaction forces"
(dashed). The v10 report printed both ratios; thresholds unchanged.
Version 10 (issue 29 item 5): the cause of Table 4.1's two failing 1b claims (Fig. 4.14 (VIII),
(XI)), which the thesis gives as friction ("due to friction ... no motion is possible at
all"): 1a_3a and 1b_3a again with Coulomb friction mu = 1.0 at the tool contacts and a 20 ms
friction reference (ours; the shipped table scene has mu = 0.3 and a 1 s reference, under
which the friction is viscous below ~1 cm/s of slip and the tool creeps along the obstacle).
The rules were written after one exploratory run of each (named in their rows); the two
failing claims keep their setup and verdict.
Version 9 (issue 29 item 5), after the v8 result had been seen: Fig. 5.6's equal slopes are
fitted until the break-away (the drawer first moving faster than 1 mm/s) instead of until the
drawer has moved 1 mm, a window that held the samples after the latch released (see the
claim's row, which also names a first, wrong v9 diagnosis; rule unchanged).
Version 8 (issue 29 item 3): the last claims the issue lists as not encoded, each written
before the run that judges it: Fig. 5.2 (the SMA removes noise and adds a lag; on the (5.9)
vertical-drawer run of Fig. 5.11, with noise of ours: the simulation has none), Fig. 5.10d
(robustness to a manual disturbance while opening the microwave door with (5.9), under Fig.
5.13: the same Sec. 5.4.3 runs) and the iCub torso drift without the clamp of Table 3.7's
task 1 (Sec. 3.3.2.1).
Version 7 (issue 29 item 3): "in the Cartesian trajectory tracking approach nu has no
relation to the slope of the forces" (Sec. 5.4.3, read with Fig. 5.11): trajectory following
on the vertical drawer at 45 deg, nu = 0.025 and 0.1 m/s beside the thesis' 0.05 m/s (ours:
the thesis runs 0.05 only); rule written before the run.
Version 6 (issue 27 item 5, issue 29 item 3): the elbow collision of Sec. 3.3.1 (Table
3.2 with a ball in the elbow's path, the SPG not told about it; task 3b against the same
without a task 3 and with task 3a; ours: the ball declared and a collision_avoidance level on
top), rules written before the first run with the ball (:data:`ELBOW_CLAIMS`).
Also in version 6 (issue 29 item 3), claims the thesis makes that no rule encoded, each written
before the run that judges it: Fig. 4.14 (VIII), the > 50 deg force misalignment of the
LBR-IV (Sec. 5.4, read with Fig. 5.11), Fig. 5.5 (SMA window: smoother but later) and
Fig. 5.6's equal slopes (Sec. 5.3.4), and the per-condition statements of the captions of
Figs. 5.16/5.17 (on Table 5.1's fixed-direction runs); the report's Gauss-function shape
(linear when fully constrained, quadratic when partially, report Ch. 5/7).
Version 5 (issue 29): the Ch. 3 baseline (Alg. C.1/C.2) runs without Ch. 4's velocity and
acceleration box, and Table 3.4 with Table 3.2's circle and start pose (rules unchanged,
the setup changes named in their rows before the run). Version 4 (issue 29): Fig. 5.13's
estimate error leaves out the initial transient (the second half of the quarter turn);
Table 3.2 and Figs. 3.14/3.15 run the thesis' static force model (their rules unchanged,
the setup change named in their rows). Version 3 (issue 21): Sec. 5.3.4 (the ACCREA trials,
Figs. 5.6/5.7) and Sec. 5.4.3 (Figs. 5.11-5.13) added; Fig. 5.11 compares what the thesis
compares; after its first results the nullspace baseline of the Ch. 3 claims takes the
velocity box by SNS (every Ch. 3 row says so). Version 2 (issue 21) wrote every rule from
the thesis. Version 1 was the one-line checks in ``reproduce.py`` (the summary texts of
docs/REPRODUCTION.md before issue 21).
"""

from collections.abc import Callable
import dataclasses
import math
from typing import Any, cast

__all__ = ['CLAIMS', 'ELBOW_CLAIMS', 'FRI_DELAY_CLAIMS', 'Claim', 'evaluate', 'VERSION']

VERSION = 11


@dataclasses.dataclass(frozen=True)
class Claim:
    """One thesis claim and its pass rule.

    Attributes:
        id: Unique name (``<experiment>.<what>``).
        experiment: Experiment name in :mod:`experiments.reproduce`.
        source: Where the thesis (or report) states it.
        thesis: The thesis value or statement.
        metric: What we measure (with unit).
        get: numbers -> our value (float or bool), from the experiment's check numbers.
        op: '<', '<=', '>', '>=', 'abs<=' (|ours - target| <= bound), 'factor' (ours
            within a factor ``bound`` of ``target``) or 'true'.
        bound: The threshold (or tolerance for 'abs<=' / 'factor').
        target: The value compared against for 'abs<=' / 'factor'.
        scale: Display factor of ours/bound (e.g. 1e3 for m -> mm).
        unit: Display unit.
        quick: Evaluated in ``--quick`` runs too (False: needs the full run).
        history: Changes after a result had been seen, and why.
    """

    id: str
    experiment: str
    source: str
    thesis: str
    metric: str
    get: Callable[[dict], Any]
    op: str
    bound: float = 0.0
    target: float | None = None
    scale: float = 1.0
    unit: str = ''
    quick: bool = True
    history: str = ''

    def rule(self):
        """The pass rule as text."""
        u = f' {self.unit}' if self.unit else ''
        target = cast(float, self.target)  # set where the op reads it ('abs<=', 'factor')
        if self.op == 'true':
            return 'holds'
        if self.op == 'abs<=':
            return f'{target * self.scale:g} +- {self.bound * self.scale:g}{u}'
        if self.op == 'factor':
            return (f'{target * self.scale / self.bound:.3g} ... '
                    f'{target * self.scale * self.bound:.3g}{u} (x/ {self.bound:g})')
        return f'{self.op} {self.bound * self.scale:g}{u}'


def _ok(c, v):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return False
    ops = {'<': lambda: v < c.bound, '<=': lambda: v <= c.bound, '>': lambda: v > c.bound,
           '>=': lambda: v >= c.bound, 'true': lambda: bool(v),
           'abs<=': lambda: abs(v - c.target) <= c.bound,
           'factor': lambda: c.target / c.bound <= v <= c.target * c.bound}
    return bool(ops[c.op]())


#: Experiments run on the nullspace baseline (Ch. 3).
_CH3 = ('table_3_2', 'k_sweep', 'speed_sweep', 'table_3_3', 'table_3_4', 'table_3_5',
        'table_3_6', 'table_3_7')
_SNS = ('v3, after its first results: the nullspace baseline saturates the velocity box '
        'inside the hierarchy (SNS) instead of clipping its result per joint (rule '
        'unchanged)')


def evaluate(experiment, numbers, quick=False, claims=None):
    """Evaluate the claims of ``experiment`` on its check numbers; a list of dict rows.

    ``claims``: the claims to look in (default :data:`CLAIMS`).
    """
    rows = []
    for c in CLAIMS if claims is None else claims:
        if c.experiment != experiment or (quick and not c.quick):
            continue
        try:
            v = c.get(numbers)
        except (KeyError, IndexError, TypeError, ZeroDivisionError):
            v = None
        if isinstance(v, bool) or c.op == 'true':
            ours = 'yes' if v else 'no'
        elif v is None:
            ours = 'n/a'
        else:
            ours = f'{float(v) * c.scale:.3g}{(" " + c.unit) if c.unit else ""}'
        rows.append({'id': c.id, 'experiment': c.experiment, 'source': c.source,
                     'thesis': c.thesis, 'metric': c.metric, 'ours': ours,
                     'value': None if v is None else (bool(v) if c.op == 'true' else float(v)),
                     'rule': c.rule(), 'passed': _ok(c, v), 'history': c.history})
    return rows


def _ratio(key, hi=-1, lo=0):
    return lambda n: n[key][hi] / n[key][lo]


_PLOT = 'no number (plot)'
_V3 = 'new in v3 (issue 21), written before the first run'
_F511 = ("v2 ran task specification (5.5) against (5.9) under this figure's name, at K = 100 "
         "Nm/rad and kappa = 10 N/s; the thesis' Fig. 5.11 compares (5.9) with the "
         'trajectory-following strategy of Sec. 5.3 on the LBR at K = 40 Nm/rad, kappa = 9 '
         'N/s, nu = 0.05 m/s, N = 500, v_th = 0.01 m/s (Sec. 5.4.3); v3 runs that')
_F513 = ('v4 (issue 29), after the v3 result had been seen: v3 took the RMS over the whole '
         'turn, which holds the 45 deg starting error, so the run length alone predicted its '
         'ratios (1.46 / 1.50 predicted, 1.50 / 1.43 seen); the thesis names the delay of the '
         'filter (5.4) as the cause, a lag while turning, so the metric is now the second half '
         'of the turn (crank angle 45-90 deg); threshold unchanged, written before the run')
_OURS = ('threshold ours (the thesis prints plots only), unchanged since it was first '
         'written')

_V6 = 'new in v6 (issue 29 item 3), written before the first run'
_V7 = 'new in v7 (issue 29 item 3), written before the first run'
_V8 = 'new in v8 (issue 29 item 3), written before the first run'
_F512 = ('v11 (issue 29), after the v10 result had been seen (its Fig. 5.12 text printed '
         'the static ratios beside the measured ones, 0.62 horizontal and 0.25 vertical): '
         'the sentence judged reads "applied erroneous forces", and Sec. 5.4.3 names the '
         'two forces of its graphs "the applied erroneous static forces ||f_s perp||" and '
         '"the measured erroneous interaction forces"; until v10 the rule read the measured '
         'force; threshold unchanged')
_V10_FRICTION = ('new in v10 (issue 29 item 5): the cause ablation of table_4_1.1b_stall and '
                 'table_4_1.1b_penetration, ours (the thesis gives no friction); rule written '
                 'after one exploratory run of each variant at mu = 1.0 and a 20 ms friction '
                 'reference (seen: the 1b_3a tool stuck at the obstacle from about 4 to 7 s '
                 'of the run; virtual penetration 15.7 mm (1b_3a) against 41.7 mm (1a_3a)); '
                 '1 s and the factor 0.5 (that of table_4_1.1b_penetration) ours')
_V6_51 = (_V6 + '; the v5 report had been read (its Table 5.1 row gives aggregates only: one '
          'of the nine fixed-direction task-specification runs does not finish), not the '
          'per-run values; the thesis discusses Figs. 5.16/5.17 after inducing the constant '
          'd_hat, so the rules read the fixed-direction runs')

_F55_QUICK = ('v6, after the first run (both rules held): full run only (quick=False; '
              'written quick=True), since its two cupboard-door runs cost 14 s of CPU, over '
              "the --quick budget's 10 s for a new claim; rule unchanged")


def _t51(n, stiffness, kappa, key, strategy):
    """Table 5.1 fixed-direction run (K, kappa): ``key``'s [joint compliance, task spec.]."""
    rows = [r for r in n['fixed_direction']['runs']
            if r['stiffness'] == stiffness and r['kappa'] == kappa]
    return rows[0][key][strategy]  # IndexError (n/a: the claim fails) when the run is missing


def _t51_time(n, stiffness, kappa, strategy):
    """Time to lift [s] of a fixed-direction run; the run's duration if it never finishes."""
    t = _t51(n, stiffness, kappa, 'time_to_open_jc_ts_s', strategy)
    return n['duration_s'] if t is None else t


CLAIMS: tuple[Claim, ...] = (
    # -- Ch. 3, LBR (Sec. 3.3.1) ---------------------------------------------------------
    Claim('table_3_2.force', 'table_3_2', 'Table 3.2, Sec. 3.3.1, Fig. 3.12(a)',
          'constant 8 N contact force while tracking the circle', 'force error RMS [N]',
          lambda n: n['force_error_rms_n'], '<', 4.0, unit='N', history=_OURS),
    Claim('table_3_2.position', 'table_3_2', 'Table 3.2, Fig. 3.12(a)',
          'circle tracked (' + _PLOT + ')', 'physical circle error RMS',
          lambda n: n['position_error_rms_m'], '<', 0.02, scale=1e3, unit='mm', history=_OURS),
    Claim('table_3_2.contact', 'table_3_2', 'Table 3.2, Fig. 3.12(a)', 'contact kept',
          'share of samples under 1 N', lambda n: n['contact_lost_share'], '<', 0.05,
          scale=100, unit='%', history=_OURS),
    Claim('table_3_2.3b_force', 'table_3_2', 'Table 3.2 task 3b', 'as 3a with joint torque '
          '0 as task 3', 'force error RMS, task 3b', lambda n: n['task3b']['force_error_rms_n'],
          '<', 4.0, unit='N', quick=False, history='new in v2 (task 3b was not run in v1); '
          'the rule of task 3a'),
    Claim('table_3_2.3b_position', 'table_3_2', 'Table 3.2 task 3b', 'circle tracked',
          'physical circle error RMS, task 3b',
          lambda n: n['task3b']['position_error_rms_m'], '<', 0.02, scale=1e3, unit='mm',
          quick=False, history='as table_3_2.3b_force'),
    Claim('table_3_2.obstacle_touched', 'table_3_2', 'Sec. 3.3.1, Fig. 3.12(a-2)',
          'an unknown obstacle blocks the path', 'force on the obstacle max (25-tick mean)',
          lambda n: n['obstacle']['max_obstacle_force_n'], '>', 3.0, unit='N', quick=False,
          history='new in v2 (the obstacle trial was not run in v1); 3 N as in Table 4.1'),
    Claim('table_3_2.obstacle_stable', 'table_3_2', 'Sec. 3.3.1, Fig. 3.12(a-2)',
          '"the manipulator remains stable" after the collision', 'peak |qdot| in the last '
          '2 s', lambda n: n['obstacle']['peak_qdot_last_2s_rad_s'], '<', 1.0, unit='rad/s',
          quick=False, history='new in v2; 1 rad/s fixed before the run'),
    Claim('k_sweep.position', 'k_sweep', 'Fig. 3.15, Sec. 3.3.1',
          'higher stiffness: better position tracking', 'position error RMS, K=400 / K=40',
          _ratio('position_error_rms_m'), '<', 0.9,
          history='margin 10 % ours, unchanged'),
    Claim('k_sweep.force', 'k_sweep', 'Fig. 3.15 caption',
          'slightly higher average force error for higher stiffness',
          'force error RMS, K=400 / K=40', _ratio('force_error_rms_n'), '>', 1.0,
          history='new in v2 (the caption states it; v1 checked the position trend only)'),
    Claim('speed_sweep.position', 'speed_sweep', 'Fig. 3.14 (K = 400 Nm/rad)',
          'position tracking decreases for faster execution', 'position error RMS, '
          '15 / 2.5 cm/s', _ratio('position_error_rms_m'), '>', 1.1,
          history="v1 ran the sweep at K = 200; v2 at the thesis' K = 400 (issue 21)"),
    Claim('speed_sweep.force', 'speed_sweep', 'Fig. 3.14 (K = 400 Nm/rad)',
          'force error increases with speed (dynamic effects)', 'force error RMS, '
          '15 / 2.5 cm/s', _ratio('force_error_rms_n'), '>', 1.1,
          history='as speed_sweep.position'),
    Claim('table_3_3.force', 'table_3_3', 'Table 3.3, Fig. 3.12(b)', '8 N while wiping',
          'force error RMS', lambda n: n['force_error_rms_n'], '<', 4.0, unit='N',
          history=_OURS),
    Claim('table_3_3.position', 'table_3_3', 'Table 3.3', 'Lissajous figure wiped '
          '("neither very accurate position nor force tracking required")',
          'physical wipe error RMS', lambda n: n['position_error_rms_m'], '<', 0.03,
          scale=1e3, unit='mm', history=_OURS),
    Claim('table_3_3.contact', 'table_3_3', 'Table 3.3', 'contact kept',
          'share of samples under 1 N', lambda n: n['contact_lost_share'], '<', 0.05,
          scale=100, unit='%', history=_OURS),
    Claim('table_3_4.limit_full', 'table_3_4', 'Sec. 3.3.1, Fig. 3.13',
          'constant orientation: a joint limit is hit (clamping)',
          'ticks with a joint within dl_crit + 1 mrad of a limit, full',
          lambda n: n['full']['ticks_at_joint_limit'], '>', 0,
          history='setup (R = 0.15 m, A7 started 6 deg from its limit) chosen in v1 so that '
          'the limit is hit (the thesis gives neither R nor the start pose)'),
    Claim('table_3_4.contact', 'table_3_4', 'Table 3.4 task 1', '6 N on the paper while '
          'drawing', 'share of samples under 1 N, worse of full / relaxed',
          lambda n: max(n['full']['contact_lost_share'], n['relaxed']['contact_lost_share']),
          '<', 0.05, scale=100, unit='%',
          history='added in v2 after the first nullspace run lost the contact (the rule of '
          'Tables 3.2/3.3, fixed in v1)'),
    Claim('table_3_4.limit_relaxed', 'table_3_4', 'Sec. 3.3.1, Fig. 3.13',
          'rotation about the pen free: the limit is avoided', 'ticks at a limit, relaxed',
          lambda n: n['relaxed']['ticks_at_joint_limit'], '<=', 0),
    Claim('table_3_4.peak_qdot', 'table_3_4', 'Sec. 3.3.1, Fig. 3.13',
          'smaller joint velocities when relaxed', 'peak |qdot|, relaxed / full',
          lambda n: n['relaxed']['peak_qdot_norm_rad_s'] / n['full']['peak_qdot_norm_rad_s'],
          '<', 1.0),
    Claim('table_3_4.discontinuity', 'table_3_4', 'Fig. 3.13 caption',
          'clamping at the limit causes a discontinuity of the joint velocities; relaxed '
          'avoids it', 'largest per-tick jump of qdot_v (2-norm), full / relaxed',
          lambda n: n['full']['max_qdot_v_jump_rad_s'] / n['relaxed']['max_qdot_v_jump_rad_s'],
          '>=', 2.0, history='new in v2 (v1 measured the jump of the measured |qdot| and '
          'did not check it); factor 2 fixed before the first v2 run'),
    Claim('table_3_5.moved', 'table_3_5', 'Table 3.5, Fig. 3.12(d)',
          'the arm can be pushed around manually', 'tool displacement max',
          lambda n: n['max_displacement_m'], '>', 0.03, scale=100, unit='cm', history=_OURS),
    Claim('table_3_5.orientation', 'table_3_5', 'Table 3.5',
          'fixed orientation held (' + _PLOT + ')', 'physical orientation error from 0.5 s '
          'after a push', lambda n: n['max_orientation_error_settled_deg'], '<', 3.0,
          unit='deg', history=_OURS),
    Claim('table_3_5.virtual', 'table_3_5', 'Table 3.5', 'fixed orientation held',
          'virtual orientation error max', lambda n: n['max_virtual_orientation_error_deg'],
          '<', 0.5, unit='deg', history=_OURS),
    # -- Ch. 3, iCub (Sec. 3.3.2) --------------------------------------------------------
    Claim('table_3_6.moved', 'table_3_6', 'Table 3.6, Fig. 3.16',
          'static interaction torques minimised (hand can be pushed)',
          'r_palm displacement max', lambda n: n['max_displacement_m'], '>', 0.03, scale=100,
          unit='cm', history=_OURS),
    Claim('table_3_6.orientation', 'table_3_6', 'Table 3.6, Fig. 3.16(a)',
          'orientation of the right hand (cup) held', 'physical orientation error from '
          '0.5 s after a push', lambda n: n['max_orientation_error_settled_deg'], '<', 3.0,
          unit='deg', history='v1 widened the settling window 0.5 -> 1 s after a failing run '
          '(the iCub return time constant ~0.33 s); v2 restores the 0.5 s written first'),
    Claim('table_3_6.virtual', 'table_3_6', 'Table 3.6', 'orientation held',
          'virtual orientation error max', lambda n: n['max_virtual_orientation_error_deg'],
          '<', 0.5, unit='deg', history=_OURS),
    Claim('table_3_6.wrist', 'table_3_6', 'Table 3.6 task 2',
          'stiff wrist joints kept at q_bar', 'wrist q_v deviation from q_bar max',
          lambda n: n['max_wrist_virtual_deviation_deg'], '<', 0.5, unit='deg',
          history=_OURS),
    Claim('table_3_6.wrist_track', 'table_3_6', 'Sec. 3.3.2.1 (wrists not compliant)',
          'the stiff wrists follow q_v', '|q - q_v| of the wrists max',
          lambda n: n['max_wrist_tracking_error_rad'], '<', 1e-3, unit='rad', history=_OURS),
    Claim('table_3_7.force', 'table_3_7', 'Table 3.7, Fig. 3.17', 'left hand wipes with '
          '7 N', 'left wrist force error RMS', lambda n: n['force_error_rms_n'], '<', 3.5,
          unit='N', history=_OURS),
    Claim('table_3_7.contact', 'table_3_7', 'Table 3.7', 'contact kept',
          'share of samples under 1 N', lambda n: n['contact_lost_share'], '<', 0.1,
          scale=100, unit='%', history=_OURS),
    Claim('table_3_7.wipe', 'table_3_7', 'Table 3.7 task 3', 'y alternates between two '
          'points (8 cm steps)', 'left hand y range', lambda n: n['left_hand_y_range_m'],
          '>=', 0.04, scale=100, unit='cm', quick=False, history=_OURS),
    Claim('table_3_7.cup_orientation', 'table_3_7', 'Table 3.7 task 5',
          'right hand keeps its initial orientation', 'orientation error max',
          lambda n: n['right_hand_orientation_error_max_deg'], '<', 3.0, unit='deg',
          history=_OURS),
    Claim('table_3_7.cup_position', 'table_3_7', 'Table 3.7 task 6',
          'right hand keeps its initial position', 'displacement max',
          lambda n: n['right_hand_displacement_max_m'], '<', 0.02, scale=1e3, unit='mm',
          history=_OURS),
    Claim('table_3_7.roll_yaw_cup_orientation', 'table_3_7', 'Table 3.7 task 1 (other '
          'reading) and task 5', 'right hand keeps its initial orientation',
          'orientation error max, torso roll and yaw clamped',
          lambda n: n['roll_yaw']['right_hand_orientation_error_max_deg'], '<', 3.0,
          unit='deg', quick=False, history='new in v2: the other reading of "joints 2 and 3"'),
    Claim('table_3_7.roll_yaw_cup_position', 'table_3_7', 'Table 3.7 task 1 (other '
          'reading) and task 6', 'right hand keeps its initial position',
          'displacement max, torso roll and yaw clamped',
          lambda n: n['roll_yaw']['right_hand_displacement_max_m'], '<', 0.02, scale=1e3,
          unit='mm', quick=False, history='as table_3_7.roll_yaw_cup_orientation'),
    Claim('table_3_7.torso_drift', 'table_3_7', 'Sec. 3.3.2.1', '"With the weight of the '
          'whole torso on joints 2 and 3, a major drift is likely to occur" (from the '
          'erroneously estimated external torques, with a higher-priority force task); '
          'clamping them "avoids the drift issue"', 'largest excursion of torso pitch or roll '
          '(measured q) over the run, Table 3.7 without task 1 (the clamp removed, ours) over '
          'the same with it', lambda n: max(n['no_clamp']['torso_drift_max_deg'][j]
                                            for j in ('torso_pitch', 'torso_roll')) /
          max(n['torso_drift_max_deg'][j] for j in ('torso_pitch', 'torso_roll')),
          '>=', 2.0, quick=False, history=_V8 + '; factor 2 ours ("major")'),
    # -- Ch. 4 (Sec. 4.3) -----------------------------------------------------------------
    Claim('table_4_1.hit', 'table_4_1', 'Fig. 4.13/4.14', 'the obstacle blocks the path in '
          'every variant', 'variants with > 3 N on the obstacle (of 4)',
          lambda n: sum(n[v]['obstacle_hit_s'] is not None for v in
                        ('1a_3a', '1b_3a', '1a_3b', '1b_3b')), '>=', 4, history=_OURS),
    Claim('table_4_1.1b_torque', 'table_4_1', 'Table 4.1 task 1b, Fig. 4.14 (II)',
          '|tau_s| <= 5 Nm', 'max |tau_s| of 1b_3a, 1b_3b from 1 s after the switch',
          lambda n: max(n[v]['max_abs_static_torque_nm'] for v in ('1b_3a', '1b_3b')),
          '<=', 5.25, unit='Nm', history='5 % over the bound allowed (ours), unchanged'),
    Claim('table_4_1.3b_force', 'table_4_1', 'Table 4.1 task 3b, Fig. 4.14 (VI)',
          '|f_y|, |f_z| <= 10 N', 'max static tangential force of 1a_3b, 1b_3b',
          lambda n: max(max(n[v]['max_abs_static_tangential_force_n'],
                            n[v]['max_abs_task_tangential_force_n'])
                        for v in ('1a_3b', '1b_3b')), '<=', 10.5, unit='N',
          history='5 % over the bound allowed (ours), unchanged'),
    Claim('table_4_1.1a_3a_torque', 'table_4_1', 'Fig. 4.14 left (IV)',
          'without the bounds the interaction grows (classical IFC)',
          'max |tau_s| of 1a_3a', lambda n: n['1a_3a']['max_abs_static_torque_nm'], '>', 6.0,
          unit='Nm', history=_OURS),
    Claim('table_4_1.1a_3a_force', 'table_4_1', 'Fig. 4.14 left (IV)',
          'forces along y and z unconstrained', 'max static tangential force of 1a_3a',
          lambda n: n['1a_3a']['max_abs_static_tangential_force_n'], '>', 12.0, unit='N',
          history=_OURS),
    Claim('table_4_1.1b_stall', 'table_4_1', 'Fig. 4.14 middle (XI)',
          'with 1b "at some point no motion is possible at all"',
          'virtual tool travel along y in the last second of 1b_3a',
          lambda n: n['1b_3a']['virtual_y_travel_last_1s_m'], '<', 0.002, scale=1e3,
          unit='mm', quick=False,
          history='new in v2 (issue 21: ours slides along the obstacle); 2 mm fixed before '
          'the run'),
    Claim('table_4_1.1b_penetration', 'table_4_1', 'Fig. 4.14 middle (VIII)', 'the torque '
          'limits lowered to 5 Nm "prevent the virtual end effector from penetrating further '
          'into the obstacle"', 'largest penetration of the virtual tool (y at the commanded '
          'q_v) beyond the obstacle face, 1b_3a / 1a_3a', lambda n:
          n['1b_3a']['max_virtual_penetration_m'] / n['1a_3a']['max_virtual_penetration_m'],
          '<', 0.5, quick=False, history=_V6 + '; factor 0.5 ours'),
    Claim('table_4_1.friction_stall', 'table_4_1', 'Fig. 4.14 middle (XI): "due to friction '
          '... at some point no motion is possible at all while the virtual end-effector '
          'penetrates the obstacle"', 'with 1b the tool stalls at the obstacle, the virtual '
          'tool beyond its face', 'cause ablation (ours: Coulomb friction mu = 1.0, 20 ms '
          'friction reference), 1b_3a: longest stretch of samples at which the physical and '
          'the virtual tool each moved less than 1 mm in the last 0.5 s while the virtual '
          'tool is beyond the obstacle face', lambda n: n['friction_1b_3a']['longest_stall_s'],
          '>=', 1.0, unit='s', quick=False, history=_V10_FRICTION),
    Claim('table_4_1.friction_penetration', 'table_4_1', 'Fig. 4.14 middle (VIII)', 'the '
          'torque limits lowered to 5 Nm "prevent the virtual end effector from penetrating '
          'further into the obstacle"', 'cause ablation (as table_4_1.friction_stall): '
          'largest penetration of the virtual tool beyond the obstacle face, 1b_3a / 1a_3a',
          lambda n: n['friction_1b_3a']['max_virtual_penetration_m'] /
          n['friction_1a_3a']['max_virtual_penetration_m'], '<', 0.5, quick=False,
          history=_V10_FRICTION),
    Claim('table_4_2.virtual', 'table_4_2', 'Table 4.2, Fig. 4.16',
          'the virtual end-effector stays in the box', 'virtual tool outside, max of K = '
          '200/50', lambda n: max(n[v]['max_virtual_outside_m'] for v in ('high_k', 'low_k')),
          '<', 1e-3, scale=1e3, unit='mm', history=_OURS),
    Claim('table_4_2.physical', 'table_4_2', 'Fig. 4.16 caption',
          'the physical end-effector can be pushed out', 'physical outside, K = 200',
          lambda n: n['high_k']['max_physical_outside_m'], '>', 1e-3, scale=1e3, unit='mm',
          history=_OURS),
    Claim('table_4_2.stiffness', 'table_4_2', 'Fig. 4.16 caption',
          'the stiffness sets the force needed to push it out', 'physical outside, '
          'K = 50 / K = 200', lambda n: n['low_k']['max_physical_outside_m'] /
          n['high_k']['max_physical_outside_m'], '>', 1.5, history=_OURS),
    Claim('table_4_3.held', 'table_4_3', 'Table 4.3, Fig. 4.17',
          'pose held while the force limits are not reached', 'position error, 5 N push',
          lambda n: n['error_small_push_m'], '<', 0.005, scale=1e3, unit='mm', history=_OURS),
    Claim('table_4_3.yields', 'table_4_3', 'Fig. 4.17', 'deviates when the limits are '
          'reached', 'position error, 25 N push', lambda n: n['error_large_push_m'], '>', 0.02,
          scale=1e3, unit='mm', history=_OURS),
    Claim('table_4_3.returns', 'table_4_3', 'Fig. 4.17', 'returns when the forces vanish',
          'error at the end / during the 25 N push',
          lambda n: n['error_end_m'] / n['error_large_push_m'], '<', 0.15, history=_OURS),
    Claim('table_4_4.along', 'table_4_4', 'Table 4.4', 'motion along z_ee allowed',
          'displacement along z_ee max', lambda n: n['max_along_z_ee_m'], '>', 0.02,
          scale=100, unit='cm', history=_OURS),
    Claim('table_4_4.perp', 'table_4_4', 'Table 4.4', 'constant position in all other '
          'directions', 'perpendicular displacement left 0.5 s after each push',
          lambda n: max(abs(p) for _, p in n['after_each_push_along_perp_m']), '<', 0.003,
          scale=1e3, unit='mm', history=_OURS),
    Claim('table_4_5.unstable', 'table_4_5', 'Sec. 4.3 (4.85), Fig. 4.18 left',
          'without (4.80)/(4.81) the regulator (K = 200, k_p = 100, k_d = 0.8) is unstable: '
          'the SPG keeps generating energy', '-int tau_5 qdot_5 dt at the end / c^2 '
          '(without PSPM)', lambda n: n['no_pspm']['energy_in_end_j'] / n['c2_j'], '<', -2.0,
          history='v1 lowered the A5 damping 2.5 -> 0.5 Nms/rad to get an instability; v2 '
          "runs the thesis' LBR-IV plant (D5 = 2.5)"),
    Claim('table_4_5.growing', 'table_4_5', 'Fig. 4.18 left', 'energy generation grows '
          'without bound', 'fall of -int tau_5 qdot_5 dt over the second half / c^2',
          lambda n: (n['no_pspm']['energy_in_mid_j'] - n['no_pspm']['energy_in_end_j']) /
          n['c2_j'], '>', 0.5, history='as table_4_5.unstable'),
    Claim('table_4_5.bounded', 'table_4_5', 'Sec. 4.2 (4.84), Fig. 4.18 right',
          'with PSPM the energy generated is bounded by c^2', 'min of -int tau_5 qdot_5 dt '
          '+ c^2 (with PSPM)', lambda n: n['pspm']['energy_in_min_j'] + n['c2_j'], '>=',
          -1e-4, scale=1e3, unit='mJ',
          history='v1 passed through a 1 mJ tolerance (50 % of c^2) at -2.07 mJ; v2: 0.1 mJ '
          '(integration tolerance)'),
    Claim('table_4_5.decays', 'table_4_5', 'Fig. 4.18 right', 'the task regulation is '
          'stabilised', '|q5 error| in the last second, with / without PSPM',
          lambda n: n['pspm']['error_amplitude_last_1s_rad'] /
          n['no_pspm']['error_amplitude_last_1s_rad'], '<', 0.5, history=_OURS),
    # -- Ch. 5 (Sec. 5.5.3) ---------------------------------------------------------------
    Claim('table_5_1.fixed_reduction', 'table_5_1', 'Sec. 5.5.3 (Table 5.1), p. text',
          'fixed d_hat: RMS |f_perp| reduced by 70 %', 'reduction, 9 runs (K x kappa)',
          lambda n: n['fixed_direction']['reduction_percent'], '>=', 70.0, unit='%',
          history="rule from v1 (>= the thesis' 70 %), unchanged"),
    Claim('table_5_1.sma_reduction', 'table_5_1', 'Sec. 5.5.3',
          'SMA estimator: RMS |f_perp| reduced by 86 %', 'reduction, 9 runs, SMA seeded '
          '45 deg off (the initialisation error the thesis names, Figs. 5.6/5.7)',
          lambda n: n['sma_estimator']['reduction_percent'], '>=', 80.0, unit='%',
          history='v1 passed with the SMA started at the true direction (it duplicated the '
          'fixed case) after the 45 deg case (-75 %) failed; v2: 45 deg is the pass case'),
    Claim('table_5_1.fixed_jc_abs', 'table_5_1', 'Sec. 5.5.3', 'fixed d_hat, previous '
          'approach: RMS |f_perp| 0.58 N', 'overall RMS |f_perp|, joint compliance',
          lambda n: n['fixed_direction']['rms_f_perp_jc_to_ts_n'][0], 'factor', 2.0, 0.58,
          unit='N', history='new in v2; factor 2 fixed before the run'),
    Claim('table_5_1.fixed_ts_abs', 'table_5_1', 'Sec. 5.5.3', 'fixed d_hat, task '
          'specification: 0.17 N', 'overall RMS |f_perp|, task specification',
          lambda n: n['fixed_direction']['rms_f_perp_jc_to_ts_n'][1], 'factor', 2.0, 0.17,
          unit='N', history='new in v2'),
    Claim('table_5_1.sma_jc_abs', 'table_5_1', 'Sec. 5.5.3', 'SMA, previous approach: '
          '11.17 N', 'overall RMS |f_perp|, joint compliance (SMA)',
          lambda n: n['sma_estimator']['rms_f_perp_jc_to_ts_n'][0], 'factor', 2.0, 11.17,
          unit='N', history='new in v2'),
    Claim('table_5_1.sma_ts_abs', 'table_5_1', 'Sec. 5.5.3', 'SMA, task specification: '
          '1.54 N', 'overall RMS |f_perp|, task specification (SMA)',
          lambda n: n['sma_estimator']['rms_f_perp_jc_to_ts_n'][1], 'factor', 2.0, 1.54,
          unit='N', history='new in v2'),
    Claim('table_5_1.lifted', 'table_5_1', 'Sec. 5.5.3', 'the 0.3 m lift is executed in '
          'every trial', 'runs that finish the 0.29 m lift (of 36; 4 in --quick)',
          lambda n: sum(sum(n[c]['opened'].values()) for c in
                        ('fixed_direction', 'sma_estimator')) / n['runs_total'], '>=', 1.0,
          history='new in v2 (v1: 4 of 9 task-specification runs never finished in 80 s); '
          'v2 runs up to 240 s (a first v2 run with 160 s left 4 of 36 unfinished)'),
    Claim('table_5_1.fig_5_16_equal_low_k', 'table_5_1', 'Fig. 5.16 caption (kappa = 10 '
          'N/s)', '"For high compliance (K = 40 Nm), the two approaches perform almost equal"',
          'RMS |f_perp|, task specification / joint compliance, K = 40, kappa = 10, fixed d_hat',
          lambda n: _t51(n, 40.0, 10.0, 'rms_f_perp_jc_ts_n', 1) /
          _t51(n, 40.0, 10.0, 'rms_f_perp_jc_ts_n', 0), 'factor', 1.5, 1.0, quick=False,
          history=_V6_51 + '; factor 1.5 ours'),
    Claim('table_5_1.fig_5_16_jc_grows', 'table_5_1', 'Fig. 5.16 caption', 'with a stiffer '
          'manipulator (K = 200 Nm) "increased erroneous forces when using the previous '
          'approach"', 'RMS |f_perp| of joint compliance, K = 200 / K = 40 (kappa = 10, fixed '
          'd_hat)', lambda n: _t51(n, 200.0, 10.0, 'rms_f_perp_jc_ts_n', 0) /
          _t51(n, 40.0, 10.0, 'rms_f_perp_jc_ts_n', 0), '>', 1.1, quick=False,
          history=_V6_51 + '; margin 10 % as the sweeps of Ch. 3'),
    Claim('table_5_1.fig_5_16_slower', 'table_5_1', 'Fig. 5.16 caption', '"The higher '
          'stiffness results also in a higher execution time"', 'time to lift 0.29 m, K = 200 '
          "/ K = 40 (kappa = 10, fixed d_hat), the smaller of the two strategies' ratios (a "
          'run that does not finish counts its full duration)',
          lambda n: min(_t51_time(n, 200.0, 10.0, s) / _t51_time(n, 40.0, 10.0, s)
                        for s in (0, 1)), '>', 1.1, quick=False,
          history=_V6_51 + '; margin 10 %'),
    Claim('table_5_1.fig_5_17_ts_low_kappa', 'table_5_1', 'Fig. 5.17 caption (K = 100 '
          'Nm/rad)', 'at kappa = 5 N/s "the proposed task specification framework generates '
          'effectively no erroneous forces"; its improved performance "is apparent"',
          'RMS |f_perp|, task specification / joint compliance, K = 100, kappa = 5, fixed d_hat',
          lambda n: _t51(n, 100.0, 5.0, 'rms_f_perp_jc_ts_n', 1) /
          _t51(n, 100.0, 5.0, 'rms_f_perp_jc_ts_n', 0), '<', 0.5, quick=False,
          history=_V6_51 + '; factor 0.5 ours'),
    Claim('table_5_1.fig_5_17_ts_rises', 'table_5_1', 'Fig. 5.17 caption', 'with kappa = 15 '
          'N/s "also the effective erroneous forces rise slightly"', 'RMS |f_perp| of task '
          'specification, kappa = 15 / kappa = 5 (K = 100, fixed d_hat)',
          lambda n: _t51(n, 100.0, 15.0, 'rms_f_perp_jc_ts_n', 1) /
          _t51(n, 100.0, 5.0, 'rms_f_perp_jc_ts_n', 1), '>', 1.0, quick=False,
          history=_V6_51 + '; "slightly": no margin'),
    Claim('table_5_1.fig_5_17_jc_flat', 'table_5_1', 'Fig. 5.17 caption', 'previous '
          'approach: the erroneous forces "are not noticeably increased by a higher '
          'exploration rate"', 'RMS |f_perp| of joint compliance, kappa = 15 / kappa = 5 (K = '
          '100, fixed d_hat)', lambda n: _t51(n, 100.0, 15.0, 'rms_f_perp_jc_ts_n', 0) /
          _t51(n, 100.0, 5.0, 'rms_f_perp_jc_ts_n', 0), '<', 1.1, quick=False,
          history=_V6_51 + '; "noticeably": 10 %, the margin of the sweeps of Ch. 3'),
    # -- Sec. 5.3.4, ACCREA (v3) ----------------------------------------------------------
    Claim('sec_5_3.success', 'sec_5_3', 'Sec. 5.3.4, Fig. 5.8', 'all tests (20 for each of '
          'cupboard door, drawer, microwave door) successful: 100 %', 'share of the 60 trials '
          '(projection on, randomised nu, SMA window and initial error) that open the '
          'mechanism with |f| <= 60 N (6 in --quick)',
          lambda n: n['success_share']['projection'], '>=', 1.0, scale=100, unit='%',
          history=_V3 + '; 60 N is ours (the thesis names no force bound)'),
    Claim('sec_5_3.projection_cancels', 'sec_5_3', 'Sec. 5.3.2 (5.6)', 'the projection '
          'cancels accumulated erroneous forces', 'median over the trial pairs of |f_perp| '
          'over the last second, projection on / off', lambda n: n['median_final_ratio'],
          '<', 0.5, history=_V3 + '; factor 0.5 fixed before the run'),
    Claim('sec_5_3.fig_5_6_persistent', 'sec_5_3', 'Sec. 5.3.4, Fig. 5.6', 'drawer with '
          'break-away force, 45 deg initial error, no projection: f_perp remains "nearly '
          '20 N" after the break-away although the estimate has converged', '|f_perp| mean '
          'over the last second, projection off',
          lambda n: n['breakaway']['no_projection']['final_f_perp_n'], 'factor', 2.0, 20.0,
          unit='N', history=_V3 + "; the drawer's break-away force (20 N) is inferred from "
          'the 20 N that remain at equal slopes of f_par and f_perp; factor 2 fixed before '
          'the run'),
    Claim('sec_5_3.fig_5_6_converged', 'sec_5_3', 'Sec. 5.3.4, Fig. 5.6', 'the direction '
          'estimate converges to the true direction', 'estimate error over the last second, '
          'projection off', lambda n: n['breakaway']['no_projection']['final_error_deg'],
          '<', 5.0, unit='deg', history=_V3 + '; 5 deg fixed before the run'),
    Claim('sec_5_3.fig_5_7_vanish', 'sec_5_3', 'Sec. 5.3.4, Fig. 5.7', 'with the projection '
          'the persistent contact forces disappear', '|f_perp| mean over the last second, '
          'projection on', lambda n: n['breakaway']['projection']['final_f_perp_n'], '<',
          2.0, unit='N', history=_V3 + '; 2 N (a tenth of the 20 N) fixed before the run'),
    Claim('sec_5_3.fig_5_6_equal_slopes', 'sec_5_3', 'Sec. 5.3.4, Fig. 5.6', 'from d_p0 45 '
          'deg off, f_par and f_perp increase "with approximately the same slope" until the '
          'break-away', 'least-squares slope of |f_perp| / that of |f_par|, from 0.1 s until '
          'the break-away (the drawer first moving faster than 1 mm/s), break-away run '
          'without projection',
          lambda n: n['breakaway']['no_projection']['slope_f_perp_breakaway_n_s'] /
          n['breakaway']['no_projection']['slope_f_par_breakaway_n_s'], 'abs<=', 0.25, 1.0,
          history=_V6 + '; +-25 % as fig_5_11.jc_slope; v9 (issue 29 item 5), after the v8 '
          'result (1.31) had been seen: v6-v8 fitted "until the drawer has moved 1 mm", a '
          'window that held the 11 samples after the latch released (|f_par| falling to 0 '
          'N, |f_perp| rising to 36 N within 20 ms); the thesis says "until the break-away", '
          'so the window now ends at the first sample at which the drawer moves faster than '
          '1 mm/s (it creeps at < 0.1 mm/s before, at > 10 mm/s after); a first v9 commit '
          '(989189d) blamed the start transient of the grasp and fitted over the second half '
          'of the old window instead, and its quick run gave 2.34: the end of the window, not '
          "its start, was the cause; the diagnosis computed the new window's ratio (1.07) "
          'before this rule was committed; rule unchanged'),
    Claim('sec_5_3.fig_5_5_lag', 'sec_5_3', 'Sec. 5.3.4, Fig. 5.5', 'cupboard door, two SMA '
          'windows: "a larger phase lag is also observed" for the larger window',
          'mean estimate error over the second half of the opening (door angle 0.3-0.6 rad), '
          "window 1.0 s / 0.3 s (the ends of the thesis' N in [300, 1000] at 1 kHz; nu = "
          '0.03 m/s and the 45 deg initial error of the break-away run, projection on: ours)',
          lambda n: n['fig_5_5']['w1.0']['mean_error_second_half_deg'] /
          n['fig_5_5']['w0.3']['mean_error_second_half_deg'], '>', 1.1, quick=False,
          history=_V6 + '; margin 10 % as the sweeps of Ch. 3; ' + _F55_QUICK),
    Claim('sec_5_3.fig_5_5_smoother', 'sec_5_3', 'Sec. 5.3.4, Fig. 5.5', '"a larger window '
          'leads to a smoother direction estimation" ("improved noise reduction")',
          'RMS of the second difference of the unit estimate per tick (its jitter; a steady '
          'turn at omega adds only (omega dt)^2) over the second half of the opening, '
          'window 1.0 s / 0.3 s',
          lambda n: n['fig_5_5']['w1.0']['rms_second_difference'] /
          n['fig_5_5']['w0.3']['rms_second_difference'], '<', 0.9, quick=False,
          history=_V6 + '; margin 10 %; the simulation has no sensor noise, so what the '
          "window smooths is the motion's own jitter; " + _F55_QUICK),
    Claim('fig_5_11.misalignment', 'fig_5_11', 'Sec. 5.4 (Fig. 2.8; Sec. 5.4.3 gives it as '
          "the cause of Fig. 5.11's trajectory-following forces)", 'for the LBR-IV the '
          'misalignment of p_v - p and f "can be easily larger than 50 deg for equal '
          'stiffness in every joint, even for descent values (> 0.1) of the manipulability mu"',
          'share of configurations with mu = sqrt(det(J J^T)) > 0.1 (tool Jacobian, m and '
          'rad; uniform in the joint limits, seeded) in which some position deviation dp '
          '(orientation deviation 0) and the static force f = K [(J J^T)^-1]_pp dp (K = k I_7, '
          'any J dq = (dp, 0)) are more than 50 deg apart',
          lambda n: n['misalignment']['share_over_50deg'], '>=', 0.1, scale=100, unit='%',
          history=_V6 + '; "easily" read as at least a tenth of the configurations (ours)'),
    # -- Sec. 5.4.3 (v3) -----------------------------------------------------------------
    Claim('fig_5_11.tf_small_error', 'fig_5_11', 'Sec. 5.4.3, Fig. 5.11 right',
          'trajectory following: erroneous forces remain, even for very small estimation '
          'errors', 'RMS |f_perp| over the second half of the lift, trajectory following '
          '(5.3 on the LBR), 10 deg', lambda n: n['admittance_10']['rms_f_perp_second_half_n'],
          '>', 1.0, unit='N', quick=False, history=_F511 + '; 1 N as in v2'),
    Claim('fig_5_11.tf_above_jc_small', 'fig_5_11', 'Sec. 5.4.3, Fig. 5.11',
          'for small errors the erroneous forces of trajectory following remain, those of '
          '(5.9) vanish', 'RMS |f_perp| second half, trajectory following / (5.9), 10 deg',
          lambda n: n['admittance_10']['rms_f_perp_second_half_n'] /
          n['joint_compliance_10']['rms_f_perp_second_half_n'], '>', 2.0, quick=False,
          history=_F511 + '; factor 2 fixed before the run'),
    Claim('fig_5_11.jc_vanish', 'fig_5_11', 'Sec. 5.4.3, Fig. 5.11 left',
          '(5.9): forces build up for a large initial error until the mechanism moves, then '
          'vanish rapidly', 'RMS |f_perp| second / first half of the lift, (5.9), 45 deg',
          lambda n: n['joint_compliance_45']['rms_f_perp_second_half_n'] /
          n['joint_compliance_45']['rms_f_perp_first_half_n'], '<', 0.5,
          history=_F511 + '; factor 0.5 as in v2'),
    Claim('fig_5_11.jc_below_tf', 'fig_5_11', 'Sec. 5.4.3, Fig. 5.11', 'the new approach '
          '(5.9) has lower erroneous forces', 'RMS |f_perp| second half, (5.9) / trajectory '
          'following, 45 deg', lambda n: n['joint_compliance_45']['rms_f_perp_second_half_n'] /
          n['admittance_45']['rms_f_perp_second_half_n'], '<', 1.0, history=_F511),
    Claim('fig_5_11.jc_slope', 'fig_5_11', 'Sec. 5.4.3', 'forces build up linearly '
          'according to kappa (9 N/s) for the proposed method', 'slope of |f| (least squares) '
          'from 0.1 s until the drawer moves 1 mm, (5.9), 45 deg',
          lambda n: n['joint_compliance_45']['force_slope_n_s'], 'abs<=', 2.25, 9.0,
          unit='N/s', history=_V3 + '; +-25 % fixed before the run'),
    Claim('fig_5_11.tf_nu_no_relation', 'fig_5_11', 'Sec. 5.4.3',
          'in the Cartesian trajectory tracking approach nu has no relation to the slope of '
          'the forces (for (5.9) they build up according to kappa)',
          'slope of |f| (as fig_5_11.jc_slope), trajectory following, 45 deg: nu = 0.1 m/s '
          'over nu = 0.025 m/s (a slope proportional to nu gives 4)',
          lambda n: n['admittance_45_nu0.1']['force_slope_n_s'] /
          n['admittance_45_nu0.025']['force_slope_n_s'], 'factor', 2.0, 1.0, quick=False,
          history=_V7 + '; within a factor 2 of equal slopes (proportional would be 4)'),
    Claim('fig_5_11.fig_5_2_noise', 'fig_5_11', 'Sec. 5.2.2, Fig. 5.2', '"The noise in '
          'the measured signal is effectively eliminated" (SMA (5.4), 0.5 s window)',
          "the estimator's SMA over 0.5 s of the tool's z velocity of the (5.9) run at 45 deg "
          'with white noise of 0.01 m/s RMS added (ours: the simulation has no sensor noise): '
          'RMS of its output minus the same SMA of the clean velocity, over the noise RMS',
          lambda n: n['fig_5_2']['noise_ratio'], '<=', 0.1, quick=False,
          history=_V8 + '; a tenfold reduction ours (white noise over 250 samples: 0.063)'),
    Claim('fig_5_11.fig_5_2_lag', 'fig_5_11', 'Sec. 5.2.2, Fig. 5.2', '"a lag in the '
          'filtered signal is introduced"', 'the delay that best aligns the SMA output (as '
          'fig_5_11.fig_5_2_noise) with the clean velocity (least squares over 0-1 s)',
          lambda n: n['fig_5_2']['lag_s'], 'abs<=', 0.05, 0.25, unit='s', quick=False,
          history=_V8 + '; an SMA of window W delays by W / 2 = 0.25 s; +-0.05 s ours'),
    Claim('fig_5_12.jc_below_tf', 'fig_5_12', 'Sec. 5.4.3, Fig. 5.12', 'horizontal drawer '
          '(nearly pure kinematic constraint): "the new approach performs better in terms of '
          'applied erroneous forces"', 'RMS static |f_s perp| (K (q_v - q) through J^-T) over '
          'the pull, (5.9) / trajectory following, 45 deg',
          lambda n: n['horizontal_ratio_static'], '<', 1.0, history=_V3 + '; ' + _F512),
    Claim('fig_5_12.less_clear', 'fig_5_12', 'Sec. 5.4.3, Fig. 5.12', '"not as clearly as '
          'in the dynamically constrained case"', 'the static ratio (as fig_5_12.jc_below_tf) '
          'horizontal over vertical drawer (45 deg)',
          lambda n: n['horizontal_ratio_static'] / n['vertical_ratio_static'], '>', 1.0,
          history=_V3 + '; ' + _F512),
    Claim('fig_5_13.success', 'fig_5_13', 'Sec. 5.4.3, Fig. 5.13', 'the new approach turns '
          'the crank, even for very small radii', 'runs that finish the quarter turn (of 5)',
          lambda n: n['turned_share'], '>=', 1.0, scale=100, unit='%', history=_V3),
    Claim('fig_5_13.radius_error', 'fig_5_13', 'Sec. 5.4.3, Fig. 5.13 left', '"one '
          'observes increasing estimation errors when shorten the radius" ("This comes from '
          'the delay, introduced by the filter (5.4)")', 'RMS estimate error over the second '
          'half of the quarter turn (crank angle 45-90 deg, after the initial transient), '
          'R = 0.10 m / R = 0.25 m (kappa = 9 N/s)',
          lambda n: n['radius_error_ratio_second_half'], '>', 1.1,
          history=_V3 + '; margin 10 % as the sweeps of Ch. 3; ' + _F513),
    Claim('fig_5_13.kappa_error', 'fig_5_13', 'Sec. 5.4.3, Fig. 5.13 right', '"increased '
          'exploration speed leads to larger estimation errors" (the delay of filter (5.4))',
          'RMS estimate error over the second half of the quarter turn (after the initial '
          'transient), kappa = 15 / 5 N/s (R = 0.17 m)',
          lambda n: n['kappa_error_ratio_second_half'], '>', 1.1,
          history=_V3 + '; margin 10 %; ' + _F513),
    Claim('fig_5_13.kappa_force', 'fig_5_13', 'Sec. 5.4.3, Fig. 5.13 right', '... and '
          'larger erroneous forces', 'RMS |f_perp|, kappa = 15 / 5 N/s (R = 0.17 m)',
          lambda n: n['kappa_force_ratio'], '>', 1.1, history=_V3 + '; margin 10 %'),
    Claim('fig_5_13.fig_5_10d_disturbed', 'fig_5_13', 'Sec. 5.4.3, Fig. 5.10d', '"The new '
          'approach also proved its robustness when manually disturbing the manipulation '
          'procedure or manipulating devices with changing required forces, e.g. microwave '
          'door"', '(5.9) on the LBR-IV opens the microwave door (0.6 rad; its latch the '
          'changing force; ball grasp; 45 deg initial error) within 30 s both undisturbed and '
          'pushed by hand (ours: 25 N downwards on the tool for 0.5 s at half the undisturbed '
          'opening time)', lambda n: (n['fig_5_10d']['undisturbed']['opened'] and
                                     n['fig_5_10d']['disturbed']['opened']),
          'true', quick=False, history=_V8 + '; the push ours'),
    Claim('fig_5_13.fig_5_10d_force', 'fig_5_13', 'Sec. 5.4.3, Fig. 5.10d', 'as '
          'fig_5_13.fig_5_10d_disturbed (robust: the opening goes on as before)', 'max |f| '
          'on the handle of the pushed run outside the push (and 0.5 s after it), within Sec. '
          "5.3.4's success bound of 60 N", lambda n: n['fig_5_10d']['disturbed'][
              'max_force_outside_push_n'], '<=', 60.0, unit='N', quick=False,
          history=_V8 + "; the 60 N bound is the harness's success bound of Sec. 5.3.4"),
    # -- report Ch. 6 (Vukcevic 2018) ------------------------------------------------------
    Claim('report_6.s1_mu', 'report_6', 'report Sec. 6.2, Fig. 6.2', 'mu* = 5 Nm (sticks)',
          'mu*, arm as described (COM 0.5 m)', lambda n: n['described']['s1_mu'], 'abs<=',
          0.01, 5.0, unit='Nm'),
    Claim('report_6.s1_qdd', 'report_6', 'report Sec. 6.2, Fig. 6.3', 'qdd = 0',
          'qdd, arm as described', lambda n: n['described']['s1_qdd'], 'abs<=', 1e-6, 0.0,
          unit='rad/s^2'),
    Claim('report_6.s2_mu', 'report_6', 'report Sec. 6.3, Fig. 6.5', '|mu*| = 10 Nm',
          '|mu*|, arm as described', lambda n: abs(n['described']['s2_mu']), 'abs<=', 0.01,
          10.0, unit='Nm'),
    Claim('report_6.s2_qdd_described', 'report_6', 'report Sec. 6.3', 'qdd = -0.44 rad/s^2',
          'qdd, arm as described (1 kg point mass at 0.5 m: I = 0.25 kg m^2)',
          lambda n: n['described']['s2_qdd'], 'abs<=', 0.005, -0.44, unit='rad/s^2'),
    Claim('report_6.s2_qdd_kdl', 'report_6', 'report Sec. 6.3', 'qdd = -0.44 rad/s^2',
          'qdd, KDL reading (COM at 1.5 m, I = 2.25 kg m^2) - an INFERENCE about the '
          "report's code, not stated in it", lambda n: n['kdl']['s2_qdd'], 'abs<=', 0.005,
          -0.44, unit='rad/s^2'),
    Claim('report_6.gauss_linear_full', 'report_6', 'report Sec. 5.6, Fig. 5.5; Ch. 7',
          '"the cost function becomes linear if a robot is fully constrained" (1-DoF arm, '
          'desired end-effector angular acceleration 5 rad/s^2)', "Z(mu) of the report's "
          'sampling method (solve_sampling, 21 mu in [-10, 10] Nm), arm as described, tip '
          'force -11 N, A_N = the unit moment about z, b_N = 5 rad/s^2: RMS residual of a '
          'straight-line fit / range of Z', lambda n: n['gauss']['full']['linear_residual'],
          '<=', 1e-6, history=_V6 + '; 1e-6 (round-off) ours'),
    Claim('report_6.gauss_quadratic_partial', 'report_6', 'report Sec. 5.6 (Fig. 5.2); Ch. 7',
          '"if a robot is partially constrained then the Gauss function to be maximized takes '
          'quadratic form" (not linear)', 'as report_6.gauss_linear_full without A_N (scenario '
          '2): RMS residual of a straight-line fit / range of Z',
          lambda n: n['gauss']['partial']['linear_residual'], '>=', 0.01,
          history=_V6 + '; 1 % ours'),
    Claim('report_6.gauss_quadratic_exact', 'report_6', 'report Sec. 5.6 (Fig. 5.2); Ch. 7',
          '... quadratic form', 'as report_6.gauss_quadratic_partial: RMS residual of a '
          'parabola fit / range of Z', lambda n: n['gauss']['partial']['quadratic_residual'],
          '<=', 1e-6, history=_V6 + '; 1e-6 (round-off) ours'),
)
#: Every Ch. 3 claim names the baseline change of v3 (its setup changed after a result).
CLAIMS = tuple(dataclasses.replace(c, history=f'{c.history}; {_SNS}' if c.history else _SNS)
               if c.experiment in _CH3 else c for c in CLAIMS)
#: The Table 3.2 stack's force model (v4): the setup changed after the v3 results.
_STATIC = ("v4 (issue 29), after the v3 results: the force task runs the thesis' static "
           'model J^+T K (q_v - q) (include_damping off); v1-v3 ran the shipped stack, whose '
           'include_damping (ours, issue 18: the IFC damping -D qdot added to the estimate) '
           'the report had not named; rule unchanged')
CLAIMS = tuple(dataclasses.replace(c, history=f'{c.history}; {_STATIC}')
               if c.experiment in ('table_3_2', 'k_sweep', 'speed_sweep') else c
               for c in CLAIMS)
#: The Ch. 3 baseline without Ch. 4's box (v5): a setup change made after the v4 results.
_NO_BOX = ("v5 (issue 29), written before the run: the nullspace baseline runs without Ch. "
           "4's joint velocity and acceleration box (20 deg/s, 500 deg/s^2, 4.31-4.33; SPG "
           'option velocity_box: false, the position limits one step ahead only), which Alg. '
           'C.1/C.2 do not have; v3/v4 ran it with the box (SNS); rule unchanged')
#: Table 3.4's circle and start pose (v5), fixed before the run.
_CIRCLE = ('v5 (issue 29), written before the run: R = 0.05 m at 0.16 Hz and the start pose '
           "of Table 3.2 (q = (0, 30, 0, -60, 0, 90, 0) deg; the thesis calls circle drawing "
           "'a modification of the surface tracking task' and gives neither R nor a pose; its "
           'Fig. 3.12(c) is a photograph, absent from the text we have) replace R = 0.15 m '
           'and A7 started 6 deg from its limit (chosen in v1 so that the limit is hit; the '
           'pen was off the table 61-77 % of the circle); the limit, if any, is reached by the '
           'motion; rule unchanged')
CLAIMS = tuple(dataclasses.replace(c, history=f'{c.history}; {_NO_BOX}')
               if c.experiment in _CH3 else c for c in CLAIMS)
CLAIMS = tuple(dataclasses.replace(c, history=f'{c.history}; {_CIRCLE}')
               if c.experiment == 'table_3_4' else c for c in CLAIMS)

#: Issue 29 item 2: Table 4.5 with a delayed FRI (``sim.fri_delay``), judged on the sweep
#: ``config/sweeps/table_4_5_fri_delay.yaml`` over FRI delay x D5 (no PSPM). Numbers:
#: ``ratio['fri<n>_D<d5>']`` = max |qdot_5| in the last 1 s of the run / max |qdot_5| in the
#: 1 s after the push (0.5-1.5 s): a motion that is exponentially stable decays (ratio -> 0),
#: one that is not keeps oscillating or grows (the SPG's acceleration limit bounds it); the
#: sweep table calls a point unstable by the same rule (ratio > 0.5). D5 =
#: 2.5 Nms/rad is our estimate of the LBR-IV's A5 damping (the thesis gives no D); the FRI
#: period is the scenario's 2 ms (ours). The experiment table_4_5_delay (experiments/ch4.py)
#: runs the two points the rules read, with D5 = 0.5 beside them.
_DELAY_HISTORY = ('issue 29, written before the first delayed run; threshold 0.5 ours (the '
                  'thesis prints plots only)')
_THESIS_4_5 = ('with K = 200, k_p = 100, k_d = 0.8 and without (4.80)/(4.81) "the intrinsic '
               'damping of the IFC and the mechanism are not enough to keep the motion '
               'exponentially stable"')
FRI_DELAY_CLAIMS = (
    Claim('table_4_5_delay.unstable_fri1', 'table_4_5_delay', 'Sec. 4.3 (4.85), Fig. 4.18 '
          'left', _THESIS_4_5, 'max |qdot_5| last 1 s / after the push, no PSPM, D5 = 2.5 '
          'Nms/rad, FRI delay 1 period (a client that answers at the end of its period)',
          lambda n: n['ratio']['fri1_D2.5'], '>', 0.5, history=_DELAY_HISTORY),
    Claim('table_4_5_delay.unstable_fri0', 'table_4_5_delay', 'Sec. 4.3 (4.85), Fig. 4.18 '
          'left', _THESIS_4_5, 'max |qdot_5| last 1 s / after the push, no PSPM, D5 = 2.5 '
          'Nms/rad, no FRI delay (the emulation before issue 29)',
          lambda n: n['ratio']['fri0_D2.5'], '>', 0.5, history=_DELAY_HISTORY),
)
CLAIMS = CLAIMS + FRI_DELAY_CLAIMS

#: Issue 27 item 5 / issue 29 item 3: the elbow collision of Sec. 3.3.1, Table 3.2's obstacle
#: trial. Setup (config/scenarios/thesis_3_2_elbow_obstacle.yaml): Table 3.2 as above (LBR-IV,
#: K = 200 Nm/rad, 8 N, circle R = 5 cm at 0.16 Hz, the nullspace baseline of Alg. C.1/C.2
#: without Ch. 4's box) in the `table` scene with a fixed ball, r = 5 cm, centre (0.04, 0.06,
#: 0.72) m in the base frame, that the SPG is not told about. The thesis gives no geometry:
#: the ball is ours, placed before any run with it where the elbow capsules (link3_geom,
#: link4_geom: the links on either side of A4) of the runs without it (tasks 1 and 2 only,
#: and task 3b) pass up to 2.5 cm inside it, for about a third of the circle, its normal
#: there with a sideways (y) part, the direction the elbow's self-motion can take.
#: Numbers: ``n['elbow'][run]``, run '3b' (tasks 1, 2, 3b), 'no_task3' (tasks 1, 2),
#: '3a' (tasks 1, 2, 3a) and 'avoid' (ours). Elbow force: per SPG tick (2 ms) the sum of the
#: MuJoCo normal contact forces (mj_contactForce) of the contacts between link3_geom /
#: link4_geom and the ball, at the state the SPG reads; 'mean_elbow_force_n' its mean over
#: the circle (t >= 2 s to the end, 14.5 s), 'peak_elbow_force_n' the largest 25-tick
#: (50 ms) moving mean; 'elbow_contacts' the MuJoCo contacts between them summed over every
#: tick of the run; distances (mj_geomDistance, elbow geoms to the ball) at the measured q
#: ('min_distance_measured_m') and at each command's q_v ('min_distance_virtual_m'); the tool
#: numbers as Table 3.2's (from 2.5 s).
_ELBOW = ('new in v6 (issue 27 item 5, issue 29 item 3), written before the first run with '
          'the ball; the ball is ours (the thesis gives no geometry), placed on the elbow path '
          'of runs without it')
_ELBOW_OURS = ("ours, not the thesis': the ball declared in the stack (obstacles:) and a "
               'collision_avoidance level (link3, link4 vs the ball; margin 20 mm, influence '
               "100 mm, gain 0.3 m/s) above tasks 1, 2, 3b, on the DAQP cascade with Ch. 4's "
               'velocity box (the nullspace baseline has no inequality levels)')
_elbow = lambda run, key: lambda n: n['elbow'][run][key]  # noqa: E731
ELBOW_CLAIMS = (
    Claim('table_3_2.elbow_blocked', 'table_3_2', 'Sec. 3.3.1, Fig. 3.12(a-2)', 'an unknown '
          'obstacle blocks the path of the manipulator (here: of the elbow)',
          'peak elbow contact force (25-tick mean), tasks 1 and 2 only (no task 3)',
          _elbow('no_task3', 'peak_elbow_force_n'), '>', 3.0, unit='N', quick=False,
          history=_ELBOW + '; 3 N as table_3_2.obstacle_touched'),
    Claim('table_3_2.elbow_compensated', 'table_3_2', 'Sec. 3.3.1', '"if the joint torque '
          'minimization subtask is specified, the nullspace of the higher priority subtasks '
          'is used to compensate for collisions occurring at the elbow"', 'mean elbow contact '
          'force over the circle, task 3b / no task 3',
          lambda n: n['elbow']['3b']['mean_elbow_force_n'] /
          n['elbow']['no_task3']['mean_elbow_force_n'], '<=', 0.5, quick=False,
          history=_ELBOW + '; factor 2 ours'),
    Claim('table_3_2.elbow_compensated_vs_3a', 'table_3_2', 'Sec. 3.3.1, Table 3.2 tasks '
          '3a/3b', 'as table_3_2.elbow_compensated, against the alternative task 3a (joint '
          'position 0)', 'mean elbow contact force over the circle, task 3b / task 3a',
          lambda n: n['elbow']['3b']['mean_elbow_force_n'] /
          n['elbow']['3a']['mean_elbow_force_n'], '<=', 0.5, quick=False,
          history=_ELBOW + '; factor 2 ours'),
    Claim('table_3_2.elbow_3b_force', 'table_3_2', 'Sec. 3.3.1, Table 3.2', 'the surface task '
          'goes on while the nullspace compensates (8 N)', 'force error RMS, elbow trial, '
          'task 3b', _elbow('3b', 'force_error_rms_n'), '<', 4.0, unit='N', quick=False,
          history=_ELBOW + "; Table 3.2's rule"),
    Claim('table_3_2.elbow_3b_position', 'table_3_2', 'Sec. 3.3.1, Table 3.2', 'the circle '
          'goes on while the nullspace compensates', 'physical circle error RMS, elbow trial, '
          'task 3b', _elbow('3b', 'position_error_rms_m'), '<', 0.02, scale=1e3, unit='mm',
          quick=False, history=_ELBOW + "; Table 3.2's rule"),
    Claim('table_3_2.elbow_3b_contact', 'table_3_2', 'Sec. 3.3.1, Table 3.2', 'contact with '
          'the surface kept', 'share of samples under 1 N, elbow trial, task 3b',
          _elbow('3b', 'contact_lost_share'), '<', 0.05, scale=100, unit='%', quick=False,
          history=_ELBOW + "; Table 3.2's rule"),
    Claim('table_3_2.elbow_avoid_virtual', 'table_3_2', 'issue 27 item 5 (Sec. 4.1: '
          'collision avoidance as an inequality task at the highest priority)', _ELBOW_OURS,
          'smallest elbow-ball distance at q_v over the commands (margin 20 mm)',
          _elbow('avoid', 'min_distance_virtual_m'), '>=', 0.019, scale=1e3, unit='mm',
          quick=False, history=_ELBOW + '; margin - 1 mm, the README guarantee'),
    Claim('table_3_2.elbow_avoid_contacts', 'table_3_2', 'issue 27 item 5', _ELBOW_OURS,
          'MuJoCo contacts elbow geoms - ball, summed over the ticks',
          _elbow('avoid', 'elbow_contacts'), '<=', 0, quick=False, history=_ELBOW),
    Claim('table_3_2.elbow_avoid_force', 'table_3_2', 'issue 27 item 5, Table 3.2',
          _ELBOW_OURS + '; the surface task goes on (8 N)', 'force error RMS, ours',
          _elbow('avoid', 'force_error_rms_n'), '<', 4.0, unit='N', quick=False,
          history=_ELBOW + "; Table 3.2's rule"),
    Claim('table_3_2.elbow_avoid_position', 'table_3_2', 'issue 27 item 5, Table 3.2',
          _ELBOW_OURS + '; the circle goes on', 'physical circle error RMS, ours',
          _elbow('avoid', 'position_error_rms_m'), '<', 0.02, scale=1e3, unit='mm',
          quick=False, history=_ELBOW + "; Table 3.2's rule"),
    Claim('table_3_2.elbow_avoid_contact', 'table_3_2', 'issue 27 item 5, Table 3.2',
          _ELBOW_OURS + '; contact with the surface kept', 'share of samples under 1 N, ours',
          _elbow('avoid', 'contact_lost_share'), '<', 0.05, scale=100, unit='%', quick=False,
          history=_ELBOW + "; Table 3.2's rule"),
)
CLAIMS = CLAIMS + ELBOW_CLAIMS
