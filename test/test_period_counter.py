"""``tick: timer``'s count of missed periods (``PeriodCounter``) against a brute-force count."""

import numpy as np

from ifc_spg.node.spg_node import PeriodCounter


def test_missed_periods_match_a_brute_force_count():
    rng = np.random.default_rng(31)
    dt = 0.002
    for _ in range(50):
        # callbacks within 0.2 periods of their slot, with gaps of 0-5 skipped periods
        skips = rng.choice([0, 0, 0, 0, 1, 2, 5], size=200)
        slots = np.cumsum(1 + skips)
        times = 10.0 + slots * dt + rng.uniform(-0.2, 0.2, size=slots.size) * dt
        counter = PeriodCounter(dt)
        for t in times:
            counter.book(t)
        summary = counter.summary()
        assert summary['missed'] == int(skips[1:].sum())
        assert summary['calls'] == slots.size
        assert summary['periods'] == int(slots[-1] - slots[0] + 1)
        assert summary['calls'] + summary['missed'] == summary['periods']
        assert abs(summary['rate'] - (slots.size - 1) / (times[-1] - times[0])) < 1e-9


def test_late_callbacks_that_bunch_up_are_not_counted_as_missed_periods():
    # a callback 0.9 periods late followed by one on time: two gaps of 1.9 and 0.1 periods
    counter = PeriodCounter(0.002)
    for t in (0.0, 0.0038, 0.004, 0.006):
        counter.book(t)
    assert counter.summary()['missed'] == 0 and counter.summary()['periods'] == 4


def test_an_unused_counter_reports_nothing():
    assert PeriodCounter(0.002).summary() == {'periods': 0, 'calls': 0, 'missed': 0,
                                              'rate': 0.0}
