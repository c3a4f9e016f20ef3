"""A flood of one log message folded: the first few shown, the rest counted, then said."""
from __future__ import annotations

import logging

from modal_spring_ros.ros.process.log_limit import RepeatLimit


def records(limit: RepeatLimit, messages: list[str]) -> list[str]:
    """Return what passes ``limit`` of ``messages`` (logged by one logger), as text."""
    shown = []
    for text in messages:
        record = logging.LogRecord('sdk', logging.ERROR, __file__, 1, text, (), None)
        if limit.filter(record):
            shown.append(record.getMessage())
    return shown


def test_a_flood_of_one_kind_is_five_lines_then_a_count_in_the_next_window():
    now = [0.0]
    limit = RepeatLimit(per_window=5, window_s=60.0, clock=lambda: now[0])
    flood = [f'unknown channel: {k}' for k in range(100_000)]
    shown = records(limit, flood)
    assert shown[:4] == flood[:4] and len(shown) == 5
    assert shown[4].startswith('unknown channel: 4 (more like it in the next 60 s')
    others = ['another kind 1', 'another kind 2']
    assert records(limit, others) == others
    now[0] = 61.0
    assert records(limit, ['unknown channel: 7']) == [
        'unknown channel: 7 (99995 more like it were not shown)']
