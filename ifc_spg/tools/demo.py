"""The simulated LBR demo (``ifc-spg demo``): surface tracking on a table, bag, metrics, plots.

    ifc-spg demo [--duration S] [-o DIR] [--no-plots] [--no-video]

Runs ``config/scenarios/demo_lbr.yaml`` offline in lockstep (sim_bridge LBR FRI joint
impedance + the SPG in one process): a KUKA LBR iiwa 14 starts 1 cm above a table,
approaches it at 1 cm/s (guarded) and presses with 8 N, then draws a 5 cm circle on the
surface while keeping the force (Table 3.2-like). Writes ``DIR/bag`` (rosbag2 MCAP),
``DIR/metrics.json``, a video ``DIR/run.mp4`` (``DIR/run.gif`` without ffmpeg; skipped with a
one-line notice where no offscreen GL exists) and ``DIR/plots/index.html`` (the video above
the figures; default ``DIR`` = ``out/demo``, replaced if it holds an old demo) and prints a
short summary.
"""

import os
from pathlib import Path
import shutil
import subprocess
import sys

from ifc_spg.errors import IfcSpgError
from ifc_spg.offline.runner import find_config_dir, run_scenario
from ifc_spg.tools.plot import plot_bag
from ifc_spg.tools.render import ffmpeg_exe

__all__ = ['run_demo', 'summary']

SCENARIO = 'demo_lbr.yaml'


def _render_video(bag, out, quiet):
    """``out/run.mp4`` (``run.gif`` without ffmpeg) of the bag, or None with a notice.

    A child process: MuJoCo picks its GL backend (``MUJOCO_GL=egl``) when it is imported,
    and this process imported it for the simulation already.
    """
    # without ffmpeg a smaller GIF: Pillow holds its frames in memory until it writes
    video, size = (out / 'run.mp4', []) if ffmpeg_exe() else \
        (out / 'run.gif', ['--size', '480x360', '--fps', '12.5'])
    for old in (out / 'run.mp4', out / 'run.gif'):
        old.unlink(missing_ok=True)
    env = {**os.environ, 'MUJOCO_GL': os.environ.get('MUJOCO_GL', 'egl')}
    proc = subprocess.run([sys.executable, '-m', 'ifc_spg.cli', 'render', str(bag), '-o',
                           str(video), '-q', *size], capture_output=True, text=True, env=env)
    if proc.returncode != 0:
        reason = (proc.stderr.strip().splitlines() or ['failed'])[-1]
        print(f'ifc-spg demo: no video ({reason})', file=sys.stderr)
        return None
    if not quiet:
        print(proc.stdout.strip(), flush=True)
    return video


def run_demo(out_dir='out/demo', duration=None, plots=True, quiet=False, video=True):
    """Run the demo scenario; returns ``(RunResult, list of PNG paths)``."""
    out = Path(out_dir)
    if (out / 'bag').exists():
        if not (out / 'metrics.json').exists() and not (out / 'bag' / 'metadata.yaml').exists():
            raise IfcSpgError(f"'{out}' holds something else than a previous demo; choose "
                              'another -o directory')
        shutil.rmtree(out / 'bag')
        shutil.rmtree(out / 'plots', ignore_errors=True)
    result = run_scenario(find_config_dir() / 'scenarios' / SCENARIO, out, duration=duration,
                          quiet=quiet)
    clip = _render_video(result.bag, out, quiet) if video else None
    pngs = []
    if plots:
        pngs = plot_bag(result.bag, out / 'plots', title='ifc_spg demo: LBR iiwa 14 surface '
                        'tracking (simulated)', video=clip)
    return result, pngs


def summary(result, pngs):
    """The text the demo prints."""
    m = result.metrics
    force = m.get('final_task_errors', {}).get('contact_force', {})
    tick = m.get('tick_time_ms', {})
    circle = m.get('task_error_rms', {})
    lines = [
        (f"ifc_spg demo: {m['duration_s']:g} s of simulated time in {m['wall_time_s']:.1f} s "
        f"(real-time factor {m['real_time_factor']:.2f}), {m['ticks']} SPG ticks at 500 Hz"),
        ('  LBR iiwa 14 (FRI joint impedance, K = 200 Nm/rad) approached the table at 1 cm/s, '
        'pressed 8 N, then circled r = 5 cm at 0.2 Hz on it'),
    ]
    if m.get('force_error_rms_n') is not None:
        filt = m.get('force_error_rms_filtered_n')
        after = (m.get('force_error_rms_options') or {}).get('after', 0.0)
        lines.append(f"  contact force error RMS vs 8 N (t > {after:g} s): "
                     f"{m['force_error_rms_n']:.2f} N"
                     + (f' raw, {filt:.2f} N over 50 ms windows' if filt is not None else ''))
    if force:
        lines.append(f"  final force error: virtual {force['virtual']:.3f} N, measured "
                     f"{force['physical']:.3f} N" if force.get('physical') is not None else '')
    if circle:
        after = (m.get('task_error_rms_options') or {}).get('after', 0.0)
        lines.append(f'  circle tracking error RMS (x, y; t > {after:g} s): virtual '
                     f"{circle.get('virtual', float('nan')) * 1e3:.1f} mm, measured "
                     f"{circle.get('physical', float('nan')) * 1e3:.1f} mm")
    lines.append(f"  max contact force {m.get('max_contact_force_n', 0):.1f} N (impact), "
                 f"min tank energy {m.get('tank_energy_min_j') or 0:.3f} J, limit violations "
                 f"{m.get('limit_violations')}, missed ticks {m.get('missed_ticks')}")
    if tick:
        lines.append(f"  SPG tick time p50 {tick['p50']:.2f} ms, p99 {tick['p99']:.2f} ms, max "
                     f"{tick['max']:.2f} ms")
    lines.append(f'  bag:     {result.bag}   '
                 '(ifc-spg bag info / replay / plot / view; Foxglove opens it)')
    lines.append(f'  metrics: {result.metrics_path}')
    video = next((p for p in (Path(result.bag).parent / n for n in ('run.mp4', 'run.gif'))
                  if p.is_file()), None)
    if video is not None:
        lines.append(f'  video:   {video}   (ifc-spg render BAG -o FILE)')
    if pngs:
        lines.append(f'  plots:   {Path(pngs[0]).parent / "index.html"} ({len(pngs)} figures)')
    return '\n'.join(line for line in lines if line)
