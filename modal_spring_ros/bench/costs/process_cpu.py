"""
CPU time a process and its descendants have used so far, read from ``/proc`` (Linux).

A node's start-up runs in its own process and in the worker processes it starts (the modes, the
spring sample): its cost is their CPU time together, while they still run (a child's time
reaches its parent's ``cutime`` only once it has exited and been waited for).
"""
from __future__ import annotations

import os
from pathlib import Path

#: clock ticks a second, the unit of ``/proc/<pid>/stat``'s times
TICKS = os.sysconf('SC_CLK_TCK') if hasattr(os, 'sysconf') else 100
PROC = Path('/proc')


def _stat_fields(pid: int) -> list[str] | None:
    try:
        text = (PROC / str(pid) / 'stat').read_text()
    except OSError:
        return None
    # the command name, in parentheses, may hold spaces: the fields follow its last ')'
    return text[text.rfind(')') + 2:].split()


def tree_cpu_seconds(pid: int) -> float | None:
    """
    Return the user and system CPU seconds of ``pid`` and of every living descendant of it.

    Children that have exited and been waited for are in their parent's own counts
    (``cutime``, ``cstime``). None where ``/proc`` cannot tell (not Linux, or ``pid`` gone).
    """
    own = _stat_fields(pid)
    if own is None:
        return None
    parents: dict[int, list[tuple[int, list[str]]]] = {}
    for entry in PROC.iterdir():
        if entry.name.isdigit() and int(entry.name) != pid:
            fields = _stat_fields(int(entry.name))
            if fields is not None:
                parents.setdefault(int(fields[1]), []).append((int(entry.name), fields))
    total, todo = 0, [(pid, own)]
    while todo:
        current, fields = todo.pop()
        # after the name: state ppid ... utime (11) stime (12) cutime (13) cstime (14)
        total += sum(int(fields[i]) for i in (11, 12, 13, 14))
        todo.extend(parents.get(current, []))
    return total / TICKS
