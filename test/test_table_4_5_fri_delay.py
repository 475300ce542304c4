"""The Table 4.5 delay sweep's metric and table (experiments/table_4_5_fri_delay.py)."""

import numpy as np

from experiments import claims
from experiments.table_4_5_fri_delay import UNSTABLE_RATIO, oscillation, summary, table_markdown


def test_oscillation_ratio_tells_decay_from_a_sustained_oscillation():
    t = np.arange(0.0, 8.0, 0.002)
    wave = np.sin(2 * np.pi * 11 * t) * (t > 0.5)
    decaying = oscillation(t, wave * np.exp(-(t - 0.5)))
    sustained = oscillation(t, wave * 0.8)
    assert decaying['ratio'] < 0.01 < UNSTABLE_RATIO < sustained['ratio'] == 1.0
    assert decaying['push'] > 0.9


def test_table_marks_the_unstable_points_and_the_rule_reads_the_same_numbers():
    numbers = {'points': [{'fri_delay': d, 'd5': 2.5, 'unstable': d == 1} for d in (0, 1)],
               'ratio': {'fri0_D2.5': 0.01, 'fri1_D2.5': 0.9}}
    text = table_markdown(numbers)
    assert '| 2.5 | 0.01 (stable) | 0.9 (**unstable**) |' in text
    assert summary(numbers).endswith('delay 0 (0 ms): none; delay 1 (2 ms): 2.5.')
    rows = {r['id']: r['passed'] for r in claims.evaluate(
        'table_4_5_delay', numbers, claims=claims.FRI_DELAY_CLAIMS)}
    assert rows == {'table_4_5_delay.unstable_fri1': True,
                    'table_4_5_delay.unstable_fri0': False}
    assert all(c.bound == UNSTABLE_RATIO for c in claims.FRI_DELAY_CLAIMS)
