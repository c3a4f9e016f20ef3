"""
How soon a thread of the node gets the interpreter back.

The node streams on one thread and takes inputs, parameter changes and TF on others, all in one
Python interpreter, one thread running Python at a time. A thread that comes back from a call
that let the others run (a publish, a wait, most numpy and rcl calls) waits until the running
thread is made to hand the interpreter over, which Python does every *switch interval*: 5 ms by
default. While another thread is busy without a break, the stream pays that wait at every such
return: a thousand clicks a second taken on a machine whose cores were busy with other work left
the node publishing 3-10 frames a second instead of 30, its clock at 0.15-0.35 of real time (4
runs in 9 of ``test_a_flood_of_clicks_keeps_the_stream_at_its_rate`` beside two busy
processes). At :data:`SWITCH_INTERVAL_S` the same floods left the stream at its rate (9 runs in
9); a switch costs microseconds, a few hundred a second at most.
"""
from __future__ import annotations

import sys

#: the node's switch interval, s (Python's default is 0.005)
SWITCH_INTERVAL_S = 0.0005


def switch_threads_often() -> None:
    """Let a waiting thread of this process run within :data:`SWITCH_INTERVAL_S`."""
    sys.setswitchinterval(SWITCH_INTERVAL_S)
