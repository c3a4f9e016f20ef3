"""
Busy processes beside a measurement: what a node meets on a machine it shares with a robot.

:class:`BusyLoad` starts processes that each spin on a core for as long as its block runs
(the stream suite's busy case: two of them beside the node on the 2-core machine, as the test
suite is run beside two busy processes), and stops them when the block ends, whatever ends it.
"""
from __future__ import annotations

import subprocess
import sys

#: what each busy process runs: a loop that never waits
SPIN = 'while True:\n    pass\n'


class BusyLoad:
    """``with BusyLoad(n):`` ``n`` processes spin, each on a core, until the block ends."""

    def __init__(self, count: int):
        if not (isinstance(count, int) and count >= 0):
            raise ValueError(f'busy processes ({count!r}) must be a whole number, at least 0')
        self.count = count
        self.processes: list[subprocess.Popen] = []

    def __enter__(self) -> BusyLoad:
        try:
            for _ in range(self.count):
                self.processes.append(subprocess.Popen([sys.executable, '-c', SPIN],
                                                       stdin=subprocess.DEVNULL,
                                                       start_new_session=True))
        except BaseException:
            self.__exit__()
            raise
        return self

    def __exit__(self, *exc_info) -> None:
        for process in self.processes:
            process.kill()
        for process in self.processes:
            process.wait()
        self.processes = []
