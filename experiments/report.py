"""The reproduction report (``REPORT.md``, ``docs/REPRODUCTION.md``).

Written by :mod:`experiments.reproduce`: the preamble, the per-experiment discussion notes
(:data:`NOTES`, their numbers filled by :data:`NOTE_FIELDS` from the run) and
:func:`write_report`.
"""

import math
from pathlib import Path
import time

from experiments import claims
from experiments.harness import _fmt

__all__ = ['FRI_PREAMBLE', 'NOTE_FIELDS', 'NOTES', 'PREAMBLE', 'note_text', 'write_report']

#: The report's header with ``--fri-delay`` (issue 29 item 2: every verdict with the delay on).
FRI_PREAMBLE = """\
**This report ran with a delayed FRI**: `python -m experiments.reproduce --fri-delay {n}`,
the LBR's FRI emulation applies each command {n} FRI period(s) ({ms} ms) after it was sent
(`sim.fri_delay`, see `sim_bridge/simulation.py` for the source), where a scenario does not
set its own delay. Ran delayed: {delayed}. Ran as in docs/REPRODUCTION.md (no FRI: the
iCub, the ACCREA, Table 5.1's worker processes, report Ch. 6; or a delay of their own):
{undelayed}. The figures are those of docs/REPRODUCTION.md and are not repeated."""

PREAMBLE = """\
Every experiment is one or more scenarios `config/scenarios/thesis_*.yaml` run with the
offline lockstep runner (SPG + MuJoCo bridge in one process, 500 Hz SPG, 1 kHz physics);
Table 5.1 uses `ifc_spg.offline.constrained_evaluate`, report Ch. 6 the dynamics solver.
The Ch. 3 scenarios run the thesis' Ch. 3 machinery: the hierarchical nullspace mapping
(Alg. C.1/C.2) without the energy tank and without the torque-limit task; Table 3.4 shows
the DAQP cascade with PSPM (ours) beside it. Since v5 (issue 29) the mapping runs without
Ch. 4's joint velocity and acceleration box (SPG option `velocity_box: false`): Alg. C.1/C.2
clamp at the position limits only. v3/v4 saturated the box inside the hierarchy (SNS,
Flacco et al. 2012), v2 clipped per joint (both named in the claims' rows).

**Pass rules.** Each claim's rule (metric, thesis value, threshold, source) is in
`experiments/claims.py` (version {version}), written from the thesis before the runs; the
thesis prints most Ch. 3/4 results as plots without numbers, so those thresholds are ours
and say so. A claim that fails is reported as failing. The *changed* column names every
setup or threshold that was changed after a result had been seen, and why.

Mapping to our setup (details in the headers of `config/tasks/table_*.yaml` and of the
scenarios): the thesis' contact surface had its normal along base x; ours is the `table`
scene under the tool, which points down, so forces act along base -z and the circles lie in
the x-y plane. Radii, frequencies and start poses the thesis does not tabulate are stated in
each scenario file.
"""


#: Discussion per experiment: Markdown templates (written by hand from the investigations of
#: issues 21 and 29). Every number a note quotes is a ``{field}`` filled by
#: :data:`NOTE_FIELDS` from the numbers of the run that writes the report; what stays is
#: setup, thesis values and prose that explains.
NOTES = {
    'table_3_2': 'Task 3a and task 3b and the obstacle trial of Fig. 3.12(a-2) (a box 3 cm '
                 "from the start in the circle's path, task 3b). The force task runs the "
                 "thesis' static model J^+T K (q_v - q) (v4). Until v3 it ran the shipped "
                 'stack, whose include_damping (issue 18, ours) adds the IFC damping -D qdot '
                 'of the sliding motion to the estimate; the report credited its lower force '
                 'error to the Ch. 3 solver. Run beside it here (ours, no claim reads it): '
                 "force error RMS {f_static} N without include_damping (the thesis' model), "
                 '{f_damping} N with it. Figs. 3.14/3.15 run the static model too. '
                 "The elbow trial (v6; the ball in the elbow's path is ours, placed before "
                 'its first run): with task 3b the mean force on the elbow is {elbow_3b} N '
                 'against {elbow_none} N without a task 3 ({elbow_ratio}; {elbow_ratio_3a} '
                 "of task 3a's), the rule asks <= 0.5. Runs added after that result (ours, no "
                 "claim) show the cause: 5 times task 3b's gain gives {elbow_gain5} N, so "
                 'the lag of the task is not it; task 3b with include_damping gives '
                 '{elbow_damping} N ({elbow_ratio_damping} of the run without a task 3). The '
                 'static torque K (q_v - q) omits the IFC damping -D qdot of the folding arm, '
                 'and task 3b balances that damping torque along the self-motion with force '
                 'on the elbow instead of moving it away: the mean force along the '
                 'self-motion is {elbow_along} N with task 3b, {elbow_along_damping} N with '
                 'include_damping, the elbow in contact {elbow_share} and '
                 '{elbow_share_damping} of the circle; peak force per turn of the circle '
                 '{elbow_turns} N with task 3b, {elbow_turns_damping} N with include_damping, '
                 '{elbow_turns_none} N without a task 3.',
    'k_sweep': "D is scaled with sqrt(K) (constant damping ratio). The caption's second "
               'statement (force error slightly higher at higher K) is a claim of its own now.',
    'speed_sweep': "Run at the caption's K = 400 Nm/rad (v1: K = 200).",
    'table_3_4': "v5 (issue 29) runs the thesis' Ch. 3 baseline without Ch. 4's velocity "
                 "box, from Table 3.2's start pose with its circle (R = 0.05 m at 0.16 Hz); "
                 'v1-v4 started A7 6 deg from its limit with R = 0.15 m, the limit hit by '
                 'construction and the pen off the table for most of the circle. Now the pen '
                 'stays on the table (contact lost in {lost_full} of the samples with constant '
                 'orientation, {lost_relaxed} relaxed), but no joint comes within dl_crit of a '
                 'limit: the closest is {closest_full} (full) and {closest_relaxed} (relaxed). '
                 'Without a clamp there is no discontinuity (ratio {jump_ratio}) and the two '
                 'variants move alike (peak |qdot| ratio {peak_ratio}: the peak_qdot claim '
                 'holds by a margin the clamp does not explain). The runs with A7 started '
                 'closer to its limit (ours, no claim): {sweep}. With constant orientation '
                 'the 5 cm circle barely turns A7 towards its limit (closest approach against '
                 'the start); relaxed, the lowest-priority posture task q = 0 turns A7 away '
                 'from it, unbounded without the box. Which limit the thesis hit depends on '
                 'its start pose and circle, which the text does not give, and on its pen '
                 'mount, which it does: the pen along y_ee, across the flange, where ours is '
                 'the tool along the flange axis (A7), so that here the rotation the relaxed '
                 'variant frees is A7 alone. What the two failing claims measure once a clamp '
                 'acts, the v1-v4 setup run again without the box (ours, no claim): with '
                 'constant orientation {v1_limit} ticks at a limit, relaxed {v1_limit_rel}; '
                 'the largest per-tick jump of qdot_v is {v1_jump} times the relaxed one '
                 '(rule >= 2) and the relaxed peak |qdot| {v1_peak} of the full one: the '
                 "thesis' mechanism, clamp and discontinuity, appears, with the pen off the "
                 'table in {v1_lost} of the samples (full, relaxed). So the claims fail because '
                 'our motion reaches no limit, not because the baseline lacks the behaviour.',
    'table_3_5': 'Without the velocity box (v5) the virtual orientation (the first level) '
                 'is held to {virtual} deg (v3/v4 saturated the box inside the hierarchy, '
                 'SNS); when the baseline clipped its result per joint (the first v3 run) it '
                 'drifted under the pushes and the claim failed.',
    'table_3_6': 'The settling window is back at the {settle} s first written (v1 widened it '
                 'to 1 s after a failing run); from {settle} s after a push the orientation '
                 'error reaches {settled} deg. In the same run: after each push '
                 '(3 N for 1 s, ours: the thesis pushes by hand) the hand returns from '
                 '{r_end} deg with a time constant of {r_tau} s (a log-linear fit down to 3 '
                 "deg): the return of the compliant arm (the thesis' K = 5 Nm/rad, D = 0.2 "
                 'Nms/rad in its joints) to the virtual one; it stays '
                 'under 3 deg from {r_t3} s after the push on; from {settle} s after each '
                 'push it reaches {r_settled} deg. The third push brings joints to the '
                 'position-limit clamp of Alg. C.2 ({r_clamps}; none in the first two), and '
                 'its return is the slow one. The virtual hand holds the '
                 'orientation throughout ({virtual} deg): the rule reads the compliance of the '
                 'physical arm after a push whose size is ours. With pushes at half the force '
                 '(ours, no claim) the hand turns {h_pushed} deg while pushed and up to '
                 '{h_settled} deg from 0.5 s after a push (returns from {h_end} deg, under 3 '
                 'deg after {h_t3} s; {h_settled_per} deg per push; clamps: {h_clamps}). So the '
                 'failure has two parts: the compliant return alone leaves the error near the '
                 '3 deg bound 0.5 s after a push that turns the hand this far (first two '
                 'pushes, and the third at half force); the limit clamps of the third '
                 'full-force push slow its return further.',
    'table_3_7': 'Both readings of the thesis\' torso "joints 2 and 3" are run: pitch + roll '
                 '(v1) and roll + yaw (1-based in our torso order). What the simulation lacks '
                 "against the thesis' setup: the real iCub's torso carries its weight on the "
                 'structure in the q_bar posture (Fig. B.3) and its joint-torque estimate '
                 'comes from a shoulder F/T sensor; ours has exact joint torques and a table '
                 'placed by assumption (not tabulated). Without the velocity box (v5) the cup '
                 'hand moves up to {disp} mm (pitch + roll reading; {disp_ry} mm roll + yaw; '
                 'bound 20 mm) while its orientation error reaches {ang} deg ({ang_ry} deg; '
                 'bound 3 deg). Where these come from, in the same runs: the clamps of Alg. '
                 'C.2 (a joint within dl_crit = 0.02 rad of a position limit, moving towards '
                 'it). Pitch + roll reading: before the first clamp ({c_first} s, {c_joint}) '
                 'the right hand turns at most {c_ori_before} deg and moves {c_disp_before} mm; '
                 'within 0.5 s after one of the {c_n} clamp onsets it turns up to '
                 '{c_ori_within} deg and moves {c_disp_within} mm, elsewhere {c_ori_out} deg '
                 'and {c_disp_out} mm. The largest error comes {c_lag} s after {c_peak_joint} '
                 'reached its clamp: the mapping then moves the set-points of the other joints '
                 'within a few ticks (the discontinuity of Fig. 3.13; no velocity box since '
                 'v5) and the compliant arm follows them late. Roll + yaw reading: '
                 '{ry_ori_before} deg and {ry_disp_before} mm before the first clamp '
                 '({ry_first} s), {ry_ori_within} deg within 0.5 s after a clamp, '
                 '{ry_ori_out} deg elsewhere. Each reading leaves one torso joint free, and '
                 'it drifts (the result line). The cause ablation clamps all three (ours, no '
                 'claim): the cup hand then turns at most {all_ang} deg and moves {all_disp} '
                 'mm, with {all_n} clamp onsets of Alg. C.2.',
    'table_4_1': 'The stalling claim of the middle column (XI) is checked (v1 did not): ours '
                 'does not stall with 1b ({travel} mm of virtual travel along y in the last '
                 'second of 1b_3a; longest stall {stall} s): at the obstacle it slides along '
                 "the face with the circle's x component, and in the last second, which the "
                 'claim reads, our circle (ours: the thesis does not give its trajectory) has '
                 'left the obstacle: the tool stays at least {gap} mm short of where it touched '
                 'the face ({f_gap} mm with friction), so the claim measures free motion '
                 'there. The obstacle and the friction of the simulated contact are '
                 'assumptions. The thesis gives '
                 'friction as the cause ("due to friction ... no motion is possible at '
                 'all"). The cause experiment (v10, ours): 1a_3a and 1b_3a again with '
                 'Coulomb friction mu = 1.0 and a 20 ms friction reference at the tool '
                 "contacts (the table scene's mu = 0.3 and 1 s reference make the friction "
                 'viscous below ~1 cm/s of slip, so the tool creeps). There the 1b tool '
                 'stalls at the obstacle for {f_stall} s with the virtual tool beyond its '
                 'face, and its virtual tool goes {f_pen_b} mm beyond the face against '
                 '{f_pen_a} mm with 1a (ratio {f_ratio}; at mu = 0.3: {pen_b} / {pen_a} mm). '
                 'The two failing claims keep the setup they were written for.',
    'table_4_5': "With the thesis' plant (D5 = {d5} Nms/rad) the lockstep loop ends with "
                 '-int tau_5 qdot_5 dt = {energy_end} mJ without PSPM (-c^2 = {c2} mJ). The '
                 'linearised loop of (4.85) over one SPG tick (spectral radius printed above, '
                 'per D5 and measurement delay; > 1 unstable) has radius {r_d5_0} at D5 = {d5} '
                 'without delay, {r_d5_20} with 20 ticks (40 ms) of delay, and {r_05_0} at D5 '
                 "= 0.5 without delay: where the first two stay under 1, the thesis' "
                 'instability needs less damping than the LBR-IV default in this model (v1 '
                 'used 0.5), or an effect the model lacks (velocity filtering, FRI timing, the '
                 "real joint's elasticity). The PSPM bound is checked to 0.1 mJ (v1: 1 mJ).",
    'table_5_1': 'The pass case is the SMA estimator seeded 45 deg off (the initialisation '
                 "error the thesis names in Sec. 5.3.4; Fig. 5.11's values are in the plot) "
                 'over the nine (K, kappa) runs; the thesis ran six SMA trials. SMA '
                 'task-specification runs whose RMS estimate error stays above 40 deg (the '
                 'estimate hardly leaves the initial 45 deg although the drawer moves): '
                 '{stuck_ts} (joint compliance: {stuck_jc}).{stuck_speed} The dead band is '
                 "Sec. 5.4.3's v_th = 10 mm/s (Sec. 5.5 names none): slower samples count as "
                 'w0 d_hat, the current estimate. The same SMA runs with v_th = w0 = {vth} mm/s '
                 '(ours, no claim) leave {stuck_low_ts} of the task-specification runs above '
                 '40 deg (joint compliance: {stuck_low_jc}); overall RMS |f_perp| {low_jc} -> '
                 '{low_ts} N ({low_red} %), against {sma_jc} -> {sma_ts} N ({sma_red} %) at 10 '
                 "mm/s and the thesis' -86 %. The two "
                 'strategies lift at very different speeds (the lift times are printed); no '
                 'matched-speed comparison is made. Absolute RMS values are compared with the '
                 "thesis' within a factor 2. Where the absolute forces come from, the cause "
                 'ablation (ours, no claim; the thesis gives no D): the fixed-direction runs '
                 "with the plant's IFC damping D scaled give overall RMS |f_perp| {abl} (joint "
                 'compliance -> task specification; ours at D x 1: {fx_jc} -> {fx_ts} N, the '
                 "thesis 0.58 -> 0.17 N). The part that falls with D is the joint damping "
                 'force D qdot, which the static models of both strategies do not see; what '
                 "remains at the smallest D is not explained by it, and the claims on Figs. "
                 "5.16/5.17 are judged on every D in the result line. In the runs themselves "
                 "the plant's damping torque -D qdot through J^{{+T}} has an RMS orthogonal "
                 'to the motion of {fd_jc} -> {fd_ts} N (fixed direction), per run {fd_ratio} '
                 'of the measured |f_perp| (joint compliance; task specification '
                 '{fd_ratio_ts}): the measured erroneous force has the size of that damping '
                 'force. Per run of joint compliance it is {fd_by_kappa}: it grows with kappa '
                 'and hardly with K (D grows with sqrt(K), the lift speed falls with K), the '
                 'opposite of '
                 "the trends the captions of Figs. 5.16/5.17 give the previous approach, whose "
                 'erroneous force the thesis attributes to its conflicting subtasks. The runs '
                 'that do not finish the lift: task specification lifts in about c K / kappa '
                 '(task 1 subtracts S^T J^{{+T}} K qdot from the force rate kappa, so the force '
                 'stops growing at a speed proportional to kappa over the Cartesian '
                 'stiffness): {lift_model}.',
    'sec_5_3': 'Per trial (seed {seed}) nu ~ U[0.01, 0.05] m/s, the SMA window ~ U[0.3, 1] s '
               "and the initial error ~ U[40, 50] deg about a random axis orthogonal to the "
               'true direction are drawn (the thesis fixes d_p0, about 45 deg off); each trial '
               'runs with and without the projection. {hz} Hz with N = window / dT, not the '
               "thesis' 1 kHz. Doors are grasped with a ball joint (connect). Success needs "
               '|f| <= {limit} N (ours; the thesis names no bound). Trials that fail without '
               'the projection: {fails_off}; with it: {fails_on}. Where the handle speed (nu '
               'times the cosine of the initial error) is under the 1 cm/s dead band, the '
               'estimate never updates and the perpendicular force grows past the bound. The '
               'drawer of Figs. 5.6/5.7 has a {breakaway} N break-away latch, inferred from '
               "the thesis' 'nearly 20 N' that remain.",
    'fig_5_11': 'Sec. 5.4.3 parameters (K = 40 Nm/rad, kappa = 9 N/s, nu = 0.05 m/s, N = '
                '500, v_th = 0.01 m/s, 500 Hz); the trajectory-following strategy is Sec. '
                "5.3's on the LBR's joint impedance. v2 compared the task specification (5.5) "
                "with (5.9) under this figure's name; that comparison is Table 5.1's. With "
                '(5.9) the force builds up at kappa until the drawer moves (slope {slope} N/s '
                'at 45 deg). The thesis has the erroneous force vanish once the estimate has '
                'converged. The static erroneous force |f_s perp| of (5.9) at 45 deg peaks at '
                '{fs_max} N in the first half of the lift and has a median of {fs_med} N over '
                'the second half, but its RMS {fs_word} from the first half to the second '
                '({fs_45} N; {fs_10} N at 10 deg), and the measured |f_perp| {fp_word} '
                '({fp_45} N at 45 deg; {fp_10} N at 10 deg). The investigation of issue 21 '
                'traced the measured rise to the joint damping force D qdot mapped through '
                'J^-T, which (5.9) does not see and '
                'which grows as the lift takes the arm towards the stretched elbow: in this '
                'run the smallest singular value of the tool Jacobian goes {sigma} and A4 '
                '{a4} deg (45 deg). The thesis gives neither the start pose nor the lift '
                'time; ours lifts in {lift} s. The thesis gives no D either (ours: the '
                "LBR-IV table's, scaled to K = 40 Nm/rad); the cause ablation reruns the four "
                "runs with the plant's D scaled and prints the failing claims' metrics "
                '(the result line above). The claim that nu has no relation to the slope of '
                "trajectory following's forces contradicts the thesis' own Sec. 5.3.1, where "
                'this strategy builds the force up "with a slope of K_p nu": with p_v moving '
                'at nu along the first estimate while the drawer holds, the slope is nu times '
                'the Cartesian stiffness along it. Ours follows that model: measured over '
                'predicted slope {tf_model} at nu = {tf_nus} m/s (the result line).',
    'fig_5_12': 'The horizontal drawer is pulled {travel} m of its 0.3 m: a probe run before '
                'the claims were evaluated had A4 reach its limit (-120 deg) before the '
                "drawer's end; at the end of this pull A4 is at {a4} deg ((5.9) / trajectory "
                'following; the claim rows name no travel). (5.9) has {h_ratio} of the RMS '
                'erroneous force, the static part K (q_v - q) through J^-T, as the sentence '
                'they judge says (v11; until v10 they read the measured force, and '
                'less_clear failed): (5.9) has {h_static} of the RMS static |f_s perp| of '
                'trajectory following here and {v_static} on the vertical drawer, '
                '{hv_static} times as large on the horizontal drawer. The measured forces, '
                'which also carry the joint damping force of the motion that (5.9) does not '
                'see, give {h_ratio} and {v_ratio}: better on both drawers, but more clearly '
                'on the horizontal one ({hv_measured}).',
    'fig_5_13': 'Quarter turns with a ball grasp (connect) and no orientation term, 45 deg '
                'initial error, the thesis estimator (N = 500, v_th = 0.01 m/s; the '
                "mechanisms evaluation's reduced crank dead band is not used). The radii "
                '(10/17/25 cm) and kappas (5/9/15 N/s) other than R = 17 cm are ours. The '
                'estimate error of the claims is the RMS over the second half of the quarter '
                'turn (crank angle 45-90 deg; error there at its start: {err_at_half} deg): '
                'the thesis traces the error to the delay of the filter (5.4), a lag while '
                'turning, and the whole-turn RMS of v3 held the 45 deg starting error, '
                'whose weight the run length sets (a turn takes {turn} s). Whole-turn ratios, '
                'for comparison with v3: radius {radius_whole}, kappa {kappa_whole}.',
    'report_6': 'The arm as the report describes it (1 kg point mass at 0.5 m, I = 0.25 kg '
                'm^2) gives qdd = {qdd_described} rad/s^2 for the -1 Nm of scenario 2; the '
                "report's -0.44 rad/s^2 comes out ({qdd_kdl} rad/s^2) with the centre of mass "
                "at 1.5 m (I = 2.25 kg m^2). The report runs its solver on KDL's "
                "ChainHdSolver_Vereshchagin (its Sec. 5.4), and KDL reads a segment's cog in "
                "the segment's tip frame. The cause experiment runs KDL itself: the arm "
                'written as a KDL Segment with the cog as the report states it, 0.5 m along '
                "x, gives {kdl_as_written} rad/s^2, the report's value; the same point in "
                "KDL's tip frame (-0.5 m) gives {kdl_convention} rad/s^2, our solver's value "
                "for the arm as described. That the report's code wrote the cog so is still an "
                'inference (the code is not published); the mechanism is measured. mu* and '
                'scenario 1 do not depend on the reading.',
}


def _kernels_line():
    """Which kernels the runs used: the closed loops amplify their last-digit differences."""
    from ifc_spg import kernels
    from ifc_spg.cascade import daqp

    return (f'Kernels: {kernels.describe()}; {daqp.describe()} (the build `./run setup` '
            'makes; the fallbacks, e.g. IFC_SPG_NATIVE=0, round differently, and closed-loop '
            'contact runs carry that into the last digits of some numbers).')


def _pct(x):
    return f'{100 * x:.0f} %'


def _arrow(pair, digits=3, scale=1.0):
    return f'{_fmt(pair[0] * scale, digits=digits)} -> {_fmt(pair[-1] * scale, digits=digits)}'


def _rises(pair):
    return 'rises' if pair[-1] > pair[0] else 'falls'


def _halves(o, key):
    return [o[f'{key}_first_half_n'], o[f'{key}_second_half_n']]


def _stuck_runs(runs, col, bound=40.0):
    """The runs whose RMS estimate error (column ``col``) stays above ``bound`` [deg]."""
    return [r for r in runs if (r['rms_error_angle_jc_ts_deg'][col] or 0.0) > bound]


def _stuck(runs, col, bound=40.0):
    hit = _stuck_runs(runs, col, bound)
    where = ', '.join(f"K = {r['stiffness']:g}/kappa = {r['kappa']:g}" for r in hit)
    return f'{len(hit)} of {len(runs)}' + (f' ({where})' if hit else '')


def _stuck_speed(runs, col, bound=40.0):
    """The mean lift speeds [mm/s] of the runs :func:`_stuck` counts, a sentence ('': none)."""
    v = [r['mean_speed_jc_ts_m_s'][col] * 1e3 for r in _stuck_runs(runs, col, bound)
         if r['mean_speed_jc_ts_m_s'][col] is not None]
    if not v:
        return ''
    span = f'{min(v):.1f}' if len(v) == 1 else f'{min(v):.1f}-{max(v):.1f}'
    return f' Their mean lift speed (travel / time): {span} mm/s.'


def _t51_rms(case, col):
    """Overall RMS |f_perp| [N] of a Table 5.1 case, joint compliance (0) or task spec. (1)."""
    return f"{case['rms_f_perp_jc_to_ts_n'][col]:.2f}"


def _lift_model_text(m, duration):
    """The sentence of :func:`experiments.ch5._lift_time_model`."""
    lo, hi = m['c_range']
    txt = (f"c = {m['c_s_n_per_nm']:.2f} (t in s, K in Nm/rad, kappa in N/s), the median over "
           f"the {m['finished']} fixed-direction runs that finish ({lo:.2f}-{hi:.2f})")
    miss = m['not_finished']
    if not miss:
        return txt + '; every run finishes'
    return txt + '; ' + '; '.join(
        f"{r['case'].replace('_', ' ')} K = {r['stiffness']:g} / kappa = {r['kappa']:g} "
        f"would take {r['predicted_s']:.0f} s" for r in miss) + \
        f' (by that model), against the {duration:g} s a run may last (ours)'


def _t51_fd_by_kappa(runs):
    """Joint compliance's damping force per run, grouped by kappa, K ascending."""
    parts = []
    for kappa in sorted({r['kappa'] for r in runs}):
        group = sorted((r for r in runs if r['kappa'] == kappa), key=lambda r: r['stiffness'])
        parts.append(' / '.join(f"{r['rms_fd_perp_jc_ts_n'][0]:.1f}" for r in group)
                     + f' N at kappa = {kappa:g} N/s (K = '
                     + ' / '.join(f"{r['stiffness']:g}" for r in group) + ' Nm/rad)')
    return '; '.join(parts)


def _t51_fd_ratio(case, col):
    """Range over the runs of the damping force's RMS |perp| over the measured one."""
    x = [r['rms_fd_perp_jc_ts_n'][col] / r['rms_f_perp_jc_ts_n'][col] for r in case['runs']]
    return f'{min(x):.2f}' if len(x) == 1 else f'{min(x):.2f}-{max(x):.2f}'


def _t51_change(case):
    """The change of RMS |f_perp| from joint compliance to task specification [%], signed."""
    return f"{-case['reduction_percent']:+.0f}"


def _failed_trials(n, mode):
    rows = [r for r in n['trials'] if not r[mode]['success']]
    return '; '.join(
        f"{r['device']} #{r['trial']} (nu = {r['nu']:.4f} m/s, handle speed "
        f"{r['nu'] * math.cos(math.radians(r['error_deg'])) * 1e3:.1f} mm/s, final estimate "
        f"error {r[mode]['final_error_deg']:.0f} deg, max |f| {r[mode]['max_force']:.0f} N)"
        for r in rows) or 'none'


def _lift_span(n, keys):
    times = [n[k]['time_to_open_s'] for k in keys if n.get(k, {}).get('time_to_open_s')]
    return f'{min(times):.1f}-{max(times):.1f}' if times else 'n/a'


def _clamp_list(per_push):
    """Alg. C.2's clamp onsets of :func:`experiments.ch3._push_clamps` as text ('none')."""
    items = [f'{j} at t = {t:.2f} s (push {i})' for i, c in enumerate(per_push, start=1)
             for t, j in c]
    return ', '.join(items) if items else 'none'


def _per_push(numbers, key, spec=None):
    """``key`` of each push's return (:func:`experiments.ch3._check_cup`), ' / '-joined.

    Formatted with ``spec``, or with :func:`_fmt` to 2 digits (None: 'n/a').
    """
    return ' / '.join(_fmt(x[key], digits=2) if spec is None else format(x[key], spec)
                      for x in numbers['returns'])


def _closest(o):
    return f"{o['closest_limit_deg']:.1f} deg from the limit of A{o['closest_limit_joint']}"


def _a7_sweep(n):
    """Table 3.4's explanatory runs: A7 started d deg from its limit (``full_a7_<d>``)."""
    parts = []
    for key in sorted((k for k in n if k.startswith('full_a7_')),
                      key=lambda k: float(k.rsplit('_', 1)[1])):
        d, rel = key.rsplit('_', 1)[1], n.get('relaxed_a7_' + key.rsplit('_', 1)[1])
        o = n[key]
        parts.append(f"from {d} deg: full {o['ticks_at_joint_limit']} ticks at a limit "
                     f"(closest {o['closest_limit_deg']:.1f} deg), relaxed "
                     + ('n/a' if rel is None else
                        f"{rel['ticks_at_joint_limit']} (peak |qdot| "
                        f"{rel['peak_qdot_norm_rad_s']:.2f} against "
                        f"{o['peak_qdot_norm_rad_s']:.2f} rad/s full)"))
    return '; '.join(parts) if parts else 'n/a (full runs only)'


_F511_KEYS = ('joint_compliance_10', 'admittance_10', 'joint_compliance_45', 'admittance_45')
_HJ, _HA = 'drawer_horizontal/joint_compliance', 'drawer_horizontal/admittance'

#: Per note: field -> numbers -> text (a field whose number the run lacks prints n/a).
def _elbow_field(run, over=None, key='mean_elbow_force_n'):
    """A note field of the elbow trial: ``key`` of ``run`` [N], or its ratio to ``over``."""
    def get(n):
        v = n['elbow'][run][key]
        return _fmt(v / n['elbow'][over][key]) if over else f'{v:.2f}'
    return get


def _elbow_turns(run):
    """A note field: the elbow trial's peak elbow force per turn of the circle [N]."""
    return lambda n: ' / '.join(f'{v:.1f}' for v in n['elbow'][run]['peak_elbow_force_per_turn_n'])


NOTE_FIELDS = {
    'table_3_2': {'f_static': lambda n: f"{n['force_error_rms_n']:.2f}",
                  'f_damping': lambda n: f"{n['damping_ours']['force_error_rms_n']:.2f}",
                  **{k: _elbow_field(*v) for k, v in {
                      'elbow_3b': ('3b',), 'elbow_none': ('no_task3',),
                      'elbow_gain5': ('3b_gain5',), 'elbow_damping': ('3b_damping',),
                      'elbow_ratio': ('3b', 'no_task3'), 'elbow_ratio_3a': ('3b', '3a'),
                      'elbow_ratio_damping': ('3b_damping', 'no_task3'),
                      'elbow_along': ('3b', None, 'mean_elbow_force_along_self_motion_n'),
                      'elbow_along_damping': ('3b_damping', None,
                                              'mean_elbow_force_along_self_motion_n')}.items()},
                  **{f'elbow_turns{suffix}': _elbow_turns(run) for suffix, run in (
                      ('', '3b'), ('_damping', '3b_damping'), ('_none', 'no_task3'))},
                  'elbow_share': lambda n: _pct(n['elbow']['3b']['ticks_in_contact_share']),
                  'elbow_share_damping': lambda n: _pct(
                      n['elbow']['3b_damping']['ticks_in_contact_share'])},
    'table_3_4': {
        'lost_full': lambda n: _pct(n['full']['contact_lost_share']),
        'lost_relaxed': lambda n: _pct(n['relaxed']['contact_lost_share']),
        'lost_full_daqp': lambda n: _pct(n['full_daqp']['contact_lost_share']),
        'lost_relaxed_daqp': lambda n: _pct(n['relaxed_daqp']['contact_lost_share']),
        'closest_full': lambda n: _closest(n['full']),
        'closest_relaxed': lambda n: _closest(n['relaxed']),
        'sweep': _a7_sweep,
        'peak_ratio': lambda n: _fmt(n['relaxed']['peak_qdot_norm_rad_s'] /
                                     n['full']['peak_qdot_norm_rad_s']),
        'jump_ratio': lambda n: _fmt(n['full']['max_qdot_v_jump_rad_s'] /
                                     n['relaxed']['max_qdot_v_jump_rad_s']),
        'v1_limit': lambda n: f"{n['v1']['limit_full']}",
        'v1_limit_rel': lambda n: f"{n['v1']['limit_relaxed']}",
        'v1_jump': lambda n: _fmt(n['v1']['jump_ratio']),
        'v1_peak': lambda n: _fmt(n['v1']['peak_ratio']),
        'v1_lost': lambda n: ' / '.join(_pct(n[v]['contact_lost_share'])
                                        for v in ('full_v1', 'relaxed_v1'))},
    'table_3_5': {'virtual': lambda n: _fmt(n['max_virtual_orientation_error_deg'], digits=2)},
    'table_3_6': {'settle': lambda n: f"{n['settle_s']:g}",
                  'r_end': lambda n: _per_push(n, 'error_at_end_deg', '.1f'),
                  'r_tau': lambda n: _per_push(n, 'tau_s'),
                  'r_t3': lambda n: _per_push(n, 'under_3deg_after_s', '.2f'),
                  'virtual': lambda n: _fmt(n['max_virtual_orientation_error_deg'], digits=2),
                  'h_pushed': lambda n: f"{n['half_push']['max_orientation_error_deg']:.1f}",
                  'h_settled': lambda n:
                      f"{n['half_push']['max_orientation_error_settled_deg']:.2f}",
                  'h_end': lambda n: _per_push(n['half_push'], 'error_at_end_deg', '.1f'),
                  'h_t3': lambda n: _per_push(n['half_push'], 'under_3deg_after_s', '.2f'),
                  'settled': lambda n: _fmt(n['max_orientation_error_settled_deg']),
                  'r_settled': lambda n: _per_push(n, 'settled_max_deg', '.2f'),
                  'h_settled_per': lambda n: _per_push(n['half_push'], 'settled_max_deg',
                                                       '.2f'),
                  'r_clamps': lambda n: _clamp_list(n['push_clamps']),
                  'h_clamps': lambda n: _clamp_list(n['half_push']['push_clamps'])},
    'table_3_7': {
        'disp': lambda n: f"{n['right_hand_displacement_max_m'] * 1e3:.1f}",
        'disp_ry': lambda n: f"{n['roll_yaw']['right_hand_displacement_max_m'] * 1e3:.1f}",
        'ang': lambda n: f"{n['right_hand_orientation_error_max_deg']:.1f}",
        'ang_ry': lambda n: f"{n['roll_yaw']['right_hand_orientation_error_max_deg']:.1f}",
        'c_first': lambda n: f"{n['clamps']['first_s']:.2f}",
        'c_joint': lambda n: n['clamps']['first_joint'],
        'c_n': lambda n: n['clamps']['onsets'],
        'c_ori_before': lambda n: f"{n['clamps']['orientation_before_first_deg']:.1f}",
        'c_disp_before': lambda n: f"{n['clamps']['displacement_before_first_m'] * 1e3:.1f}",
        'c_ori_within': lambda n: f"{n['clamps']['orientation_within_deg']:.1f}",
        'c_disp_within': lambda n: f"{n['clamps']['displacement_within_m'] * 1e3:.1f}",
        'c_ori_out': lambda n: f"{n['clamps']['orientation_outside_deg']:.1f}",
        'c_disp_out': lambda n: f"{n['clamps']['displacement_outside_m'] * 1e3:.1f}",
        'c_lag': lambda n: f"{n['clamps']['peak_onset'][0]:.2f}",
        'c_peak_joint': lambda n: n['clamps']['peak_onset'][1],
        'ry_first': lambda n: f"{n['roll_yaw']['clamps']['first_s']:.2f}",
        'ry_ori_before': lambda n:
            f"{n['roll_yaw']['clamps']['orientation_before_first_deg']:.1f}",
        'ry_disp_before': lambda n:
            f"{n['roll_yaw']['clamps']['displacement_before_first_m'] * 1e3:.1f}",
        'ry_ori_within': lambda n: f"{n['roll_yaw']['clamps']['orientation_within_deg']:.1f}",
        'ry_ori_out': lambda n: f"{n['roll_yaw']['clamps']['orientation_outside_deg']:.1f}",
        'all_ang': lambda n: f"{n['all_torso']['right_hand_orientation_error_max_deg']:.2f}",
        'all_disp': lambda n: f"{n['all_torso']['right_hand_displacement_max_m'] * 1e3:.1f}",
        'all_n': lambda n: n['all_torso']['clamps']['onsets']},
    'table_4_1': {
        'travel': lambda n: f"{n['1b_3a']['virtual_y_travel_last_1s_m'] * 1e3:.1f}",
        'stall': lambda n: f"{n['1b_3a']['longest_stall_s']:.1f}",
        'gap': lambda n: f"{n['1b_3a']['last_1s_short_of_touch_m'] * 1e3:.0f}",
        'f_gap': lambda n: f"{n['friction_1b_3a']['last_1s_short_of_touch_m'] * 1e3:.0f}",
        'f_stall': lambda n: f"{n['friction_1b_3a']['longest_stall_s']:.1f}",
        'f_pen_b': lambda n: f"{n['friction_1b_3a']['max_virtual_penetration_m'] * 1e3:.1f}",
        'f_pen_a': lambda n: f"{n['friction_1a_3a']['max_virtual_penetration_m'] * 1e3:.1f}",
        'f_ratio': lambda n: _fmt(n['friction_1b_3a']['max_virtual_penetration_m'] /
                                  n['friction_1a_3a']['max_virtual_penetration_m']),
        'pen_b': lambda n: f"{n['1b_3a']['max_virtual_penetration_m'] * 1e3:.1f}",
        'pen_a': lambda n: f"{n['1a_3a']['max_virtual_penetration_m'] * 1e3:.1f}"},
    'table_4_5': {
        'd5': lambda n: f"{n['linear_loop']['damping_5']:g}",
        'energy_end': lambda n: f"{n['no_pspm']['energy_in_end_j'] * 1e3:.2f}",
        'c2': lambda n: f"{-n['c2_j'] * 1e3:g}",
        'r_d5_0': lambda n: _fmt(n['linear_loop']['radius'][
            f"D{n['linear_loop']['damping_5']:g}_delay0"], digits=4),
        'r_d5_20': lambda n: _fmt(n['linear_loop']['radius'][
            f"D{n['linear_loop']['damping_5']:g}_delay20"], digits=4),
        'r_05_0': lambda n: _fmt(n['linear_loop']['radius']['D0.5_delay0'], digits=4)},
    'table_5_1': {'stuck_ts': lambda n: _stuck(n['sma_estimator']['runs'], 1),
                  'stuck_jc': lambda n: _stuck(n['sma_estimator']['runs'], 0),
                  'stuck_speed': lambda n: _stuck_speed(n['sma_estimator']['runs'], 1),
                  'vth': lambda n: f"{n['sma_estimator_vth']['v_threshold_m_s'] * 1e3:g}",
                  'stuck_low_ts': lambda n: _stuck(n['sma_estimator_vth']['runs'], 1),
                  'stuck_low_jc': lambda n: _stuck(n['sma_estimator_vth']['runs'], 0),
                  'low_jc': lambda n: _t51_rms(n['sma_estimator_vth'], 0),
                  'low_ts': lambda n: _t51_rms(n['sma_estimator_vth'], 1),
                  'low_red': lambda n: _t51_change(n['sma_estimator_vth']),
                  'sma_jc': lambda n: _t51_rms(n['sma_estimator'], 0),
                  'sma_ts': lambda n: _t51_rms(n['sma_estimator'], 1),
                  'sma_red': lambda n: _t51_change(n['sma_estimator']),
                  'abl': lambda n: '; '.join(
                      f"{_t51_rms(v['fixed_direction'], 0)} -> "
                      f"{_t51_rms(v['fixed_direction'], 1)} N at D x {k}"
                      for k, v in n['damping_ablation'].items()),
                  'fd_jc': lambda n: f"{n['fixed_direction']['rms_fd_perp_jc_to_ts_n'][0]:.2f}",
                  'fd_ts': lambda n: f"{n['fixed_direction']['rms_fd_perp_jc_to_ts_n'][1]:.2f}",
                  'fd_ratio': lambda n: _t51_fd_ratio(n['fixed_direction'], 0),
                  'fd_ratio_ts': lambda n: _t51_fd_ratio(n['fixed_direction'], 1),
                  'fd_by_kappa': lambda n: _t51_fd_by_kappa(n['fixed_direction']['runs']),
                  'lift_model': lambda n: _lift_model_text(n['lift_time_model'],
                                                           n['duration_s']),
                  'fx_jc': lambda n: _t51_rms(n['fixed_direction'], 0),
                  'fx_ts': lambda n: _t51_rms(n['fixed_direction'], 1)},
    'sec_5_3': {'seed': lambda n: f"{n['seed']}", 'hz': lambda n: f"{1 / n['dt']:.0f}",
                'limit': lambda n: f"{n['force_limit_n']:g}",
                'fails_off': lambda n: _failed_trials(n, 'no_projection'),
                'fails_on': lambda n: _failed_trials(n, 'projection'),
                'breakaway': lambda n: f"{n['breakaway_setup']['force']:g}"},
    'fig_5_11': {
        'slope': lambda n: _fmt(n['joint_compliance_45']['force_slope_n_s']),
        'fs_max': lambda n: _fmt(n['joint_compliance_45']['max_fs_perp_first_half_n']),
        'fs_med': lambda n: _fmt(n['joint_compliance_45']['median_fs_perp_second_half_n']),
        'fs_word': lambda n: _rises(_halves(n['joint_compliance_45'], 'rms_fs_perp')),
        'fs_45': lambda n: _arrow(_halves(n['joint_compliance_45'], 'rms_fs_perp')),
        'fs_10': lambda n: _arrow(_halves(n['joint_compliance_10'], 'rms_fs_perp')),
        'fp_word': lambda n: _rises(_halves(n['joint_compliance_45'], 'rms_f_perp')),
        'fp_45': lambda n: _arrow(_halves(n['joint_compliance_45'], 'rms_f_perp')),
        'fp_10': lambda n: _arrow(_halves(n['joint_compliance_10'], 'rms_f_perp')),
        'sigma': lambda n: _arrow(n['joint_compliance_45']['jacobian_sigma_min_start_end'],
                                  digits=2),
        'a4': lambda n: _arrow(n['joint_compliance_45']['a4_start_end_deg'], digits=2),
        'lift': lambda n: _lift_span(n, _F511_KEYS),
        'tf_model': lambda n: ' / '.join(
            _fmt(v['measured_n_s'] / v['predicted_n_s'], digits=2)
            for v in n['tf_slope_model'].values()),
        'tf_nus': lambda n: ' / '.join(n['tf_slope_model'])},
    'fig_5_12': {
        'travel': lambda n: f"{n[_HJ]['travel_m']:.3g}",
        'a4': lambda n: f"{n[_HJ]['a4_start_end_deg'][1]:.0f} / "
                        f"{n[_HA]['a4_start_end_deg'][1]:.0f}",
        'h_ratio': lambda n: _fmt(n['horizontal_ratio'], digits=2),
        'v_ratio': lambda n: _fmt(n['vertical_ratio'], digits=2),
        'h_static': lambda n: _fmt(n['horizontal_ratio_static'], digits=2),
        'v_static': lambda n: _fmt(n['vertical_ratio_static'], digits=2),
        'hv_static': lambda n: _fmt(n['horizontal_ratio_static'] / n['vertical_ratio_static'],
                                    digits=2),
        'hv_measured': lambda n: _fmt(n['horizontal_ratio'] / n['vertical_ratio'],
                                      digits=2)},
    'fig_5_13': {
        'err_at_half': lambda n: ', '.join(
            f"{r['error_angle_at_half_turn_deg']:.1f}" for r in n['runs']),
        'radius_whole': lambda n: _fmt(n['radius_error_ratio']),
        'kappa_whole': lambda n: _fmt(n['kappa_error_ratio']),
        'turn': lambda n: '{:.1f}-{:.1f}'.format(
        *(f(t for t in (r['time_to_open_s'] for r in n['runs']) if t is not None)
          for f in (min, max)))},
    'report_6': {'qdd_described': lambda n: f"{n['described']['s2_qdd']:.3g}",
                 'qdd_kdl': lambda n: f"{n['kdl']['s2_qdd']:.3g}",
                 'kdl_as_written': lambda n: f"{n['kdl_native']['as_written']:.3g}",
                 'kdl_convention': lambda n: f"{n['kdl_native']['kdl_convention']:.3g}"},
}


class _NotAvailable(dict):
    def __missing__(self, key):
        return 'n/a'


def note_text(name, numbers, notes=None):
    """The discussion note of experiment ``name``, its fields filled from ``numbers``."""
    template = (NOTES if notes is None else notes).get(name)
    if not template:
        return ''
    values = _NotAvailable()
    for key, get in NOTE_FIELDS.get(name, {}).items():
        try:
            values[key] = get(numbers)
        except (KeyError, IndexError, TypeError, ValueError, ZeroDivisionError,
                AttributeError):
            values[key] = 'n/a'
    return template.format_map(values)


def _cell(x):
    return str(x).replace('|', '/').replace('\n', ' ')


def write_report(rows, path, quick=False, figure_prefix='', notes=None, preamble=None,
                 wall_s=None):
    """The reproduction report (Markdown): the per-claim table, then one section each.

    Args:
        rows: Result rows of :func:`run_experiments` (with ``claims``).
        path: Output file.
        quick: The rows come from ``--quick`` runs.
        figure_prefix: Prefix of the figure paths.
        notes: Experiment name -> discussion paragraph (Markdown).
        preamble: Text after the title (default :data:`PREAMBLE`).
        wall_s: Wall time of the whole run [s] (printed when given).
    """
    preamble = PREAMBLE.format(version=claims.VERSION) if preamble is None else preamble
    cl = [c for r in rows for c in r.get('claims', [])]
    n_pass = sum(c['passed'] for c in cl)
    thesis = [r for r in rows if not r.get('ours')]
    ours = [r for r in rows if r.get('ours')]
    failed = [c['id'] for c in cl if not c['passed']]
    cmd = 'python -m experiments.reproduce' + (' --quick' if quick else '')
    lines = ['# Reproduction of the thesis experiments (simulation)', '',
             f'Generated by `{cmd}` ({time.strftime("%Y-%m-%d")})' +
             (f', {wall_s / 60:.1f} min wall.' if wall_s is not None else '.') +
             f' {_kernels_line()}', '']
    if preamble:
        lines += [preamble, '']
    counted = (f"{sum(r['passed'] for r in thesis)} of the {len(thesis)} thesis experiments "
               'reproduced (all of their claims hold)')
    if ours:  # a cause test of ours is not a thesis experiment: counted apart
        counted += (f"; {sum(r['passed'] for r in ours)} of {len(ours)} of our own "
                    f"experiments ({', '.join(r['name'] for r in ours)}: tests of a cause)")
    lines += [f'Summary: {n_pass} of {len(cl)} claims hold; {counted}.' +
              (f' Failing: {", ".join(failed)}.' if failed else ''), '',
              '| claim | source | thesis | metric | ours | rule | verdict | changed |',
              '|---|---|---|---|---|---|---|---|']
    for c in cl:
        lines.append(f"| {c['id']} | {_cell(c['source'])} | {_cell(c['thesis'])} | "
                     f"{_cell(c['metric'])} | {_cell(c['ours'])} | {_cell(c['rule'])} | "
                     f"{'holds' if c['passed'] else '**fails**'} | {_cell(c['history'])} |")
    lines.append('')
    for r in rows:
        verdict = 'reproduced' if r['passed'] else '**not reproduced**'
        lines += [f"## {r['table']} ({r['name']})", '', f"Claim: {r['claim']}.", '',
                  f"Result: {verdict} - {r['summary']}.", '']
        for c in r.get('claims', []):
            lines.append(f"- {c['id']}: {c['metric']} = {c['ours']} (rule {c['rule']}): "
                         f"{'holds' if c['passed'] else '**fails**'}")
        if r.get('claims'):
            lines.append('')
        note = note_text(r['name'], r.get('numbers') or {}, notes)
        if note:
            lines += [note, '']
        if r['scenarios']:
            cmds = ' '.join(f'`ifc-spg run config/scenarios/{s} -o out/{Path(s).stem}`'
                            for s in r['scenarios'])
            lines += [f'Scenarios: {cmds}; all runs and the check: '
                      f"`python -m experiments.reproduce --only {r['name']}`.", '']
        else:
            lines += [f"Command: `python -m experiments.reproduce --only {r['name']}`.", '']
        if r['figure']:
            lines += [f"![{r['name']}]({figure_prefix}{r['figure']})", '']
    Path(path).write_text('\n'.join(lines) + '\n', encoding='utf8')
