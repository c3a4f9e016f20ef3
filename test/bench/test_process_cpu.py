"""The CPU time of a process tree: a node's start-up counts its worker processes too."""
from __future__ import annotations

import os
import subprocess
import sys
import time

from modal_spring_ros.bench.costs.process_cpu import tree_cpu_seconds
import pytest

#: a parent that burns 0.3 s of CPU and a child of its own that burns 0.6 s, then both wait
_BURNERS = '''
import subprocess, sys, time
def burn(seconds):
    end = time.process_time() + seconds
    while time.process_time() < end:
        pass
child = subprocess.Popen([sys.executable, '-c', """
import sys, time
end = time.process_time() + 0.6
while time.process_time() < end:
    pass
print('done', flush=True)
time.sleep(60)
"""], stdout=subprocess.PIPE, text=True)
burn(0.3)
child.stdout.readline()
print('ready', flush=True)
time.sleep(60)
'''


@pytest.mark.skipif(not os.path.isdir('/proc/self'), reason='reads /proc (Linux)')
def test_a_process_and_its_living_child_are_counted_together():
    parent = subprocess.Popen([sys.executable, '-c', _BURNERS], stdout=subprocess.PIPE,
                              text=True, start_new_session=True)
    try:
        assert parent.stdout.readline().strip() == 'ready'
        total = tree_cpu_seconds(parent.pid)
        fields = open(f'/proc/{parent.pid}/stat').read().rsplit(')', 1)[1].split()
        own = (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')
        # both burns (0.9 s) and the two interpreters' start-up, which the parent alone lacks
        assert 0.85 <= total < 5.0
        assert own < total - 0.5
    finally:
        os.killpg(parent.pid, 9)
        parent.wait()


def test_a_process_that_is_gone_has_no_figure():
    done = subprocess.Popen([sys.executable, '-c', 'pass'])
    done.wait()
    time.sleep(0.05)
    assert tree_cpu_seconds(done.pid) is None
