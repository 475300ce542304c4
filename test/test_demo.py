"""The demo runs end to end with a short duration and prints where its files are."""

import json

import pytest

from ifc_spg.cli.demo import main


@pytest.mark.slow
def test_demo_short(tmp_path, capsys):
    out = tmp_path / 'demo'
    assert main(['--duration', '4.0', '-o', str(out), '-q']) == 0
    text = capsys.readouterr().out
    assert str(out / 'bag') in text and 'index.html' in text and 'tick time p50' in text
    m = json.loads((out / 'metrics.json').read_text())
    assert m['ticks'] == 2000 and m['limit_violations'] == 0 and m['missed_ticks'] == 0
    # pressing on the table after the approach (t = 3.5 s): virtual force at 8 N
    # 0.5 s into the circle: the modelled and the measured force are within 2 N of 8 N
    assert m['final_task_errors']['contact_force']['virtual'] < 2.0
    assert m['final_task_errors']['contact_force']['physical'] < 2.0
    assert (out / 'plots' / 'index.html').is_file()
    # the video of the run, shown above the figures (no GL backend: a one-line notice)
    video = next((out / n for n in ('run.mp4', 'run.gif') if (out / n).is_file()), None)
    if video is not None:
        assert 'video:' in text and video.stat().st_size > 10_000
        assert f'../{video.name}' in (out / 'plots' / 'index.html').read_text()
    # a second run replaces the old demo output (its video is not looked at: not rendered)
    assert main(['--duration', '0.1', '-o', str(out), '-q', '--no-plots', '--no-video']) == 0
    assert json.loads((out / 'metrics.json').read_text())['ticks'] == 50
