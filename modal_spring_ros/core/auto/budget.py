"""
What planning may cost: a share of the full run it would replace.

Users pay whole runs. A plan that steps a hundred times cheaper but took several full runs'
worth of pilots to choose is a loss, so planning is budgeted as an adaptive solver budgets its
error estimate: the full run's cost over the run's length is known before anything is measured
(its step from its stability limit, its cost from the work model,
:mod:`~modal_spring_ros.core.auto.work_model`), and measuring may spend at most
``PLANNING_SHARE`` of it: of the cheapest full run, at its longest stable step, even where the
default step misses (priced on the dearer full run a plan then replaces, a plan the work model
put at half that run's cost won, and cost 2.4 times it as a whole process). Where even the
cheapest measurement (the full reference over the pilot's window by step doubling, and the plan
once) passes that, or would cost more than the plan could save, there is nothing to win: the
full run is the answer, its step checked by its own step doubling over as much of the window as
the budget affords (:func:`~modal_spring_ros.core.auto.unplanned_full.unplanned_full`).

A run with no length (the node streams until it is stopped) has no budget: whatever planning
costs, it is paid once and saved every second after.

Everything is in modelled work (us of one core): no clock is read, so the same scene and run
length give the same choice on any machine and under any load.
"""
from __future__ import annotations

import dataclasses
import math

from modal_spring_ros.core.auto.sibling_check import DOUBLING_WORK
from modal_spring_ros.core.auto.work_model import work_per_second
from modal_spring_ros.core.simulations import Simulation

#: Share of the full run's projected work (over the run's length) that planning may spend.
PLANNING_SHARE = 0.1
#: Where a plan could save much, planning may spend up to this many times its share, and at
#: most this share of what the plan would save (so a plan that fails costs at most twice the
#: share beside the full run, and only where winning saves four times what was spent).
WIDEN, SAVING_SHARE = 2.0, 0.25
#: A run whose full run costs less than this (modelled us) is run as the full run without
#: planning: choosing modes and building a plan's coordinates take tens to hundreds of
#: milliseconds that the work model does not count, as much as such a run could save.
SMALL_RUN_US = 1e6
#: What making a plan costs on a scene too large for every mode (modelled us), fitted to the
#: set-up of sheets of 5,000-10,000 particles (the modes' shift-invert solves took 0.8-1.3 us
#: per free DOF and mode solved for, their derivatives 120-140 us per free DOF, a spring
#: sample's training 200 us per spring at 0.3 %): per free DOF and mode solved; per free DOF;
#: per spring (each plan of other coordinates trains its own).
SETUP_US = {'modes': 1.35, 'derivatives': 140.0, 'training': 200.0}
#: The full reference over a window costs its run at a step and at half of it: three runs' worth.
REFERENCE_RUNS = 3.0


@dataclasses.dataclass
class PlanningBudget:
    """
    Modelled work planning may spend, and what it has spent (us of one core).

    :ivar limit_us: what it may spend (``inf``: not budgeted).
    :ivar full_us: the full run's projected work over the run (``inf``: no length).
    """

    limit_us: float = math.inf
    full_us: float = math.inf
    spent_us: float = 0.0
    widened: bool = False

    @classmethod
    def for_run(cls, full: Simulation, run_s: float | None,
                share: float | None = PLANNING_SHARE) -> 'PlanningBudget':
        """Budget ``share`` of ``full``'s work over ``run_s`` (None for either: unbudgeted)."""
        if run_s is None or share is None:
            return cls()
        projected = work_per_second(full) * run_s
        return cls(share * projected, projected)

    @property
    def small(self) -> bool:
        """Tell whether the whole full run costs less than ``SMALL_RUN_US``: too little to plan."""
        return self.full_us < SMALL_RUN_US

    @property
    def bounded(self) -> bool:
        return math.isfinite(self.limit_us)

    @property
    def remaining_us(self) -> float:
        return max(0.0, self.limit_us - self.spent_us)

    def widen(self, saving_us: float) -> None:
        """
        Let planning spend more where the plan would save ``saving_us`` (modelled).

        Up to ``WIDEN`` times what it may spend, and at most ``SAVING_SHARE`` of the saving.
        """
        if self.bounded and not self.widened:
            self.widened = True
            self.limit_us = max(self.limit_us, min(WIDEN * self.limit_us,
                                                   SAVING_SHARE * saving_us))

    def raise_to(self, limit_us: float) -> None:
        """Let planning spend up to ``limit_us`` in all where that is more (a saving pays)."""
        self.limit_us = max(self.limit_us, limit_us)

    def affords(self, work_us: float) -> bool:
        """Tell whether ``work_us`` more stays within the limit."""
        return self.spent_us + work_us <= self.limit_us

    def spend(self, work_us: float) -> None:
        """Count ``work_us`` of planning (modelled us) as spent."""
        self.spent_us += work_us

    def release(self, work_us: float) -> None:
        """Give back ``work_us`` counted for work that was never done (a plan never made)."""
        self.spent_us -= work_us

    def charge(self, sim: Simulation, seconds: float) -> None:
        """Count ``sim`` stepped over ``seconds`` of simulated time."""
        self.spend(work_per_second(sim) * seconds)

    def describe_left(self) -> str:
        """
        Say what planning may still spend, and of what budget (a refusal's "beyond ...").

        :meth:`affords` counts what was spent: a refusal names what was left, not only the
        budget (a plan refused at 3.2 s against a budget of 3.6 s is refused for what is left).
        """
        whole = (f'the planning budget of {self.limit_us / 1e6:.3g} s '
                 f"({self.limit_us / self.full_us:.0%} of the full run's)")
        if self.spent_us <= 0.0:
            return whole
        return f'the {self.remaining_us / 1e6:.3g} s left of {whole}'

    def describe(self) -> str:
        """Say what planning spent of what budget ('' where it has none)."""
        if not self.bounded:
            return ''
        return (f'planning {self.spent_us / 1e6:.3g} s of CPU (modelled) of its budget '
                f'{self.limit_us / 1e6:.3g} s, {self.limit_us / self.full_us:.0%} of the full '
                f"run's {self.full_us / 1e6:.3g} s")


def setup_work(model, sampled: bool, modes_solved: int) -> float:
    """
    Return what making a plan costs before it is measured, us (modelled).

    Its modes (``modes_solved`` so far: :func:`modes_work`), their derivatives and, with
    ``sampled`` springs, training a sample. Counted against the budget like the pilot's runs,
    for scenes beyond the dense limit (a small scene's modes are one dense eigensolve, and it
    trains no sample).
    """
    return (modes_work(model, modes_solved) + model.n_free_dof * SETUP_US['derivatives']
            + (training_work(model) if sampled else 0.0))


def modes_work(model, solved: int) -> float:
    """Return what solving for ``solved`` modes (summed over solves) costs, us (modelled)."""
    return SETUP_US['modes'] * model.n_free_dof * solved


def training_work(model) -> float:
    """Return what training a spring sample for a set of coordinates costs, us (modelled)."""
    return SETUP_US['training'] * model.scene.n_springs


def measuring_floor(full: Simulation, plan: Simulation, sibling_us: float,
                    window_s: float) -> float:
    """
    Return the least a pilot can spend, us: the plan once, and the cheaper reference.

    The full reference costs the full run's step doubling (priced at ``DOUBLING_WORK`` runs at
    its longest stable step); the plan's richer sibling ``sibling_us`` per simulated second.
    """
    return window_s * (work_per_second(plan)
                       + min(DOUBLING_WORK * work_per_second(full), sibling_us))


def worth_measuring(budget: PlanningBudget, full: Simulation, plan: Simulation,
                    sibling_us: float, window_s: float, run_s: float) -> str:
    """
    Return why measuring ``plan`` is not worth it ('' where it is).

    Not within the budget (widened where the plan would save much: :meth:`PlanningBudget.
    widen`), or costing more than the plan could save over ``run_s`` (the plan's work against
    the full run's).
    """
    if not budget.bounded:
        return ''
    floor = measuring_floor(full, plan, sibling_us, window_s)
    saving = (work_per_second(full) - work_per_second(plan)) * run_s
    budget.widen(saving)
    if not budget.affords(floor):
        return (f'measuring a plan would cost at least {floor / 1e6:.3g} s of CPU (modelled), '
                f'beyond {budget.describe_left()}')
    if floor >= saving:
        return (f'measuring a plan would cost {floor / 1e6:.3g} s of CPU (modelled), more than '
                f'it could save ({max(saving, 0.0) / 1e6:.3g} s)')
    return ''
