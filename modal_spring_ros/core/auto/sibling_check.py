"""
The full run over the start of the pilot's window: a check on a richer plan as the reference.

Where the full run over the whole window is beyond the pilot's budget (a large scene), a plan is
measured against its richer sibling. A sibling shares what the modal coordinates cannot follow
(a cloth's slack regions turn nonlinear at millimetres: plan and sibling agreed to 0.06 % and
were 100 % off the full run). So the full run is still run, converged in its step, over as much
of the window's start as the budget affords (at least ``MIN_SHARE`` of the window: a shorter
start tells too little), and the pilot measures every run against it as well
(:mod:`~modal_spring_ros.core.auto.pilot`): a plan's error is the larger of the two.
"""
from __future__ import annotations

import math
from typing import Callable

from modal_spring_ros.core.auto.measured_error import converged_trajectory
from modal_spring_ros.core.auto.work_model import work_per_second
from modal_spring_ros.core.simulations import Simulation
import numpy as np

#: Shortest start checked, as a share of the window's samples.
MIN_SHARE = 0.1
#: Step doubling from the longest stable step usually converges after two halvings (runs at
#: h, h / 2 and h / 4): the start is priced at this many times one run.
DOUBLING_WORK = 7.0


def full_run_start(full: Callable[[float, float], Simulation], sample_s: float, samples: int,
                   accuracy: float, work: float) -> np.ndarray | None:
    """
    Return the full run's converged trajectory over the first samples ``work`` affords.

    ``full(longest_dt, sample_s)`` builds the full run; ``accuracy`` is the relative step error
    its step doubling must reach; ``work`` the modelled work allowed for all its runs, us. None
    where fewer than ``MIN_SHARE`` of the ``samples`` are affordable, or the run diverges.
    """
    longest = full(math.inf, sample_s)
    per_sample = DOUBLING_WORK * work_per_second(longest) * sample_s
    count = min(samples, int(work / per_sample)) if per_sample > 0.0 else samples
    if count < max(2, math.ceil(MIN_SHARE * samples)):
        return None
    found = converged_trajectory(lambda dt: full(dt, sample_s), longest.dt, sample_s, count,
                                 accuracy, work / (count * sample_s))
    return None if found is None else found[0]
