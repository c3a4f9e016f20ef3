"""
A flood of one log message folded into a few lines and a count.

A library that logs once per bad request (a WebSocket client asking for 100,000 unknown
channels) would otherwise print 100,000 lines. :class:`RepeatLimit` lets the first
``per_window`` records of one kind through in each window (a kind: the logger and the message
with its numbers blanked, so ``unknown channel: 17`` and ``unknown channel: 18`` are one kind),
says once that more are not shown, and the first record of the next window says how many were
not.
"""
from __future__ import annotations

import logging
import re
import time
from typing import Callable

#: records of one kind shown in a window
PER_WINDOW = 5
#: the window, s
WINDOW_S = 60.0
#: kinds remembered at most (a flood of distinct messages cannot grow the table without bound)
MAX_KINDS = 1000
NUMBER = re.compile(r'\d+')


class RepeatLimit(logging.Filter):
    """Let the first records of each kind through per window; count the rest."""

    def __init__(self, per_window: int = PER_WINDOW, window_s: float = WINDOW_S,
                 clock: Callable[[], float] = time.monotonic):
        super().__init__()
        self.per_window, self.window_s, self._clock = per_window, window_s, clock
        self._kinds: dict[tuple[str, str], list] = {}     # kind -> [window start, seen, hidden]

    def filter(self, record: logging.LogRecord) -> bool:  # noqa: A003 (logging's name)
        kind = (record.name, NUMBER.sub('#', record.getMessage()))
        now = self._clock()
        seen = self._kinds.get(kind)
        if seen is None or now - seen[0] >= self.window_s:
            hidden = seen[2] if seen is not None else 0
            if len(self._kinds) >= MAX_KINDS:
                self._kinds.clear()
            self._kinds[kind] = [now, 1, 0]
            if hidden:
                self._append(record, f' ({hidden} more like it were not shown)')
            return True
        seen[1] += 1
        if seen[1] <= self.per_window:
            if seen[1] == self.per_window:
                self._append(record, f' (more like it in the next {self.window_s:g} s are '
                                     'counted, not shown)')
            return True
        seen[2] += 1
        return False

    @staticmethod
    def _append(record: logging.LogRecord, text: str) -> None:
        record.msg, record.args = record.getMessage() + text, ()
