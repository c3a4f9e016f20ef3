"""
The full run where no plan is made: the longest step that meets the tolerance, checked.

Where measuring a plan would cost more than the budget, or than the plan could save
(:mod:`~modal_spring_ros.core.auto.budget`), the full run is the answer: at the step its modes
predict within the tolerance where they predict one, else the one ``method full`` takes, checked
by its own step doubling over as much of the pilot's window as the budget affords, and its error
said measured, predicted, or not measured (and why).
"""
from __future__ import annotations

import functools
import math
from typing import Callable

from modal_spring_ros.core.auto.budget import PlanningBudget, REFERENCE_RUNS
from modal_spring_ros.core.auto.full_candidate import (BY_ITSELF, by_step_doubling,
                                                       head_start, STEP_ORDER)
from modal_spring_ros.core.auto.plan import (AMPLIFYING, BEYOND_LINEAR, BEYOND_MODES, NOT_FOUND,
                                             PilotReport, TOUCHES_UNSEEN, UNCONVERGED)
from modal_spring_ros.core.auto.step_error import StepPrediction
from modal_spring_ros.core.auto.watch.amplification import (amplifies, describe_rate,
                                                            start_growth, WINDOW_S as TWIN_S)
from modal_spring_ros.core.auto.work_model import work_per_second
from modal_spring_ros.core.simulations import Simulation

#: What a search for the step over the whole window may spend whatever its run costs (us,
#: modelled): a small scene whose default step misses may need a tenth to a fortieth of it
#: (random scene 0 over 3 s: 13 s of runs for the step that meets 1 %, its run 0.12 s).
SEARCH_FLOOR_US = 3e7
#: A step-doubling check of the full run covers at least this many samples.
MIN_CHECK_SAMPLES = 2
#: A step longer than the default is checked over as much of the run's start as this share of
#: what it saves over the run pays for, where that is more than the budget affords (so the
#: whole run never costs more than at the default step): a curved shell's 0.05 s start, what a
#: tenth of its 2 s run paid for, agreed with a prediction the run then measured 4.2 times; its
#: first 0.125 s measured 1.5 times the prediction, its first 0.25 s twice (half the saving paid
#: for 0.27 s, and cost 1.07 times as much on sheet_32x32_resonance over 6 s).
LONGER_CHECK_SHARE = 0.25


def unplanned_full(full: Callable[[float, float], Simulation], budget: PlanningBudget,
                   default_dt: float, window_s: float, horizon_s: float, tolerance: float,
                   margin: float, samples: int, reason: str,
                   prediction: StepPrediction | None = None,
                   saving_pays: bool = True) -> tuple[Simulation, PilotReport]:
    """
    Return the full run at the longest step that meets the tolerance, checked.

    ``prediction`` is the longest stable step every mode, stepped under the scene's loads
    with the period error and damping the integrator gives it, is predicted to keep within
    ``margin * tolerance`` over the run (:mod:`~modal_spring_ros.core.auto.step_error`; from
    the lowest modes only on a scene beyond the dense limit; None: no prediction, a scene with
    colliders or driven too fast for the modes it has). The step run is that one
    where it is longer than the default (``default_dt``: the one ``--method full`` takes, the
    scene's or half the stability limit), else the default: a user pays no more than the full
    run they would have run, and less where its default step is needlessly short.

    That step is checked by step doubling (against its run at half the step) over as much of the
    window's start as the budget affords, at least ``MIN_CHECK_SAMPLES`` of its ``samples``; a
    step longer than the default over as much as ``LONGER_CHECK_SHARE`` of what it saves pays
    for, where that is more and the full run is the answer (``saving_pays``; not where it is
    a plan's rival once the budget is spent: what that saves is the plan's to win).
    With a prediction, the check is of the prediction: where the start is within
    :data:`~.step_error.AGREEMENT` times the error predicted over that start (or within
    ``margin * tolerance``), the prediction holds where it was measured and the step is the
    answer, its error the one predicted over the run (with what the start measured beyond the
    modes a large scene's prediction has, grown over the run:
    :meth:`~.step_error.StepPrediction.confirmed`), said so (a start's transient is often beyond
    the tolerance of the whole run: judged against it, random scenes whose default step met the
    tolerance had their step searched over the whole window, at up to ten times the run's cost).
    A start can miss an error that grows later, which the prediction sees: where it puts the
    default step beyond the tolerance itself, the step run is the longest predicted within the
    margin, checked the same way.

    Without a prediction, or where the start disproves it, the step is the answer where that
    start is within ``margin * tolerance``, its error reported over the start it was measured
    on (a drift fitted to a fraction of the slowest period extrapolates the start's transient,
    not a drift); where the prediction left modes out (a scene beyond the dense limit), the
    run's error is the modes' prediction plus what the start measured beyond it, grown over the
    run (:meth:`~.step_error.StepPrediction.run_error`): the modes left out, rung by the
    drive's start, drift over the run as a start alone cannot show; so is a step longer than
    the default's (a saving the prediction alone offers: a curved shell's start 1.47 times its
    prediction was confirmed, and the run measured 4.3 times it, 2.9 times the tolerance),
    what the start measured beyond the prediction grown as the prediction grows from that
    start, whether the start confirmed it or not. A step longer than the
    default that misses is not halved (its half is shorter than the default): the default step
    is run, its error the longer step's scaled by the square of the steps' ratio (the
    integrator's order) where that is within the margin and the scene has no colliders, with
    nothing stepped again, else measured by its own step doubling. Where the step run then
    misses, the run misses the tolerance, so it is no baseline to stay near: the step is halved
    by step doubling over the whole window, its error extrapolated over ``horizon_s``, whatever
    that costs (on random scenes the full run needed a tenth to a fortieth of its stability
    limit to meet 1 % over 3 s). A scene with colliders is checked over the whole window where
    the budget affords it: its touches come when they come (a start checked a random scene's
    default step at 0.05 % where it missed 0.3 % by 2.6 times once the object reached a
    sphere). Where it does not (a short run: checking it whole costs twice the run), a start
    that misses has its step sought as above, and one that meets the tolerance says nothing of
    the touches: the default step, its error not measured (``TOUCHES_UNSEEN``).

    Some runs have no error to promise. A start that moved far beyond what the modes predict
    (:meth:`~.step_error.StepPrediction.beyond`; a soft skin crumpling: 1.72 % measured where
    0.01 % was predicted) is no smooth motion: no step's error is scaled from another's there,
    and where such a start passes its check it says nothing of the rest of the run (whose
    finer runs may part by 30 %): the default step is run, its error not measured, said why
    (``BEYOND_MODES``). Nor is anything predicted where the modes' own motion is no small
    displacement (:attr:`~.step_error.StepPrediction.holds`: it moves springs' ends apart by
    their length or more; a sheet turned 30 degrees, 49 % strain, was predicted at a quarter of
    what its step measured): the default step, and where only its start is checked, its error
    not measured (``BEYOND_LINEAR``). Where halving the step stops shrinking its error
    (:func:`~.full_candidate.by_step_doubling` stalls), the run converges in no step: the
    default step, its error not measured (``UNCONVERGED``), planning bounded (it once halved
    without end). The whole window's search costs at most what the run does at its default step
    (or ``SEARCH_FLOOR_US``): where it finds no step within that, the default step, its error
    not measured (``NOT_FOUND``; a soft mesh turned 90 degrees once searched it for over 8
    minutes, the run at the default step costing 33 s, its halved runs still 49 % apart). Nor
    is it made where a twin of the start moved by a hair parts from it exponentially
    (:mod:`~.watch.amplification`; that mesh: e-fold every 0.013 s): ``AMPLIFYING``.
    """
    sample_s = window_s / samples
    step = default_dt
    # a start far beyond the modes, or modes whose motion is no small displacement: no smooth
    # motion is predicted, and a start within the tolerance says nothing of the run
    beyond = nonlinear = prediction is not None and not prediction.holds
    if nonlinear:
        reason += (f"; the modes' motion moves springs' ends apart by up to "
                   f'{prediction.predictor.reach:.2g} times their length: no step is predicted '
                   'from them')
        prediction = None
    if prediction is not None:      # its starts read on the check's own samples
        prediction = prediction.sampled(sample_s)
    if prediction is not None and prediction.error_at(default_dt) > tolerance:
        # the default misses over the run: the longest step predicted within the margin, its
        # start checked as the budget affords (a longer search would cost more than the run)
        step = prediction.step
        reason += (f'; the default step is predicted beyond the tolerance '
                   f'({prediction.error_at(default_dt):.2%} over the run, the modes stepped with '
                   f'the period error and damping of the step): the longest step predicted within '
                   f'it ({step:.3g} s)')
    elif prediction is not None and prediction.step > default_dt:
        step = prediction.step
        reason += (f'; the longest step predicted within the tolerance ({step:.3g} s, '
                   f'{step / default_dt:.2g} times the default step)')
    checked = full(step, sample_s)
    rate = work_per_second(checked)
    longer = step > default_dt     # a saving the prediction alone offers
    if longer and saving_pays:     # pays for a start long enough to see it
        saving = (work_per_second(full(default_dt, sample_s)) - rate) * horizon_s
        budget.raise_to(budget.spent_us + LONGER_CHECK_SHARE * saving)
    affordable = budget.remaining_us / (REFERENCE_RUNS * rate * sample_s) if rate > 0 else 0
    count = int(min(samples, max(MIN_CHECK_SAMPLES, affordable)))
    checked_s = count * sample_s
    grown: StepPrediction | None = None     # where a start alone is grown over the run
    stepped: dict = {}         # every run's samples, once: a second look steps nothing again

    def doubling(samples_: int, over_s: float, allowed: float, work_per_s: float,
                 first_dt: float) -> tuple[Simulation, float]:
        before = len(stepped)
        found = by_step_doubling(full, sample_s, samples_, over_s, allowed, work_per_s,
                                 first_dt=first_dt, stepped=stepped)
        if len(stepped) > before:
            budget.charge(found[0], REFERENCE_RUNS * samples_ * sample_s)
        return found

    if prediction is not None and prediction.predictor is not None:
        # the prediction checked where it is cheap: the start, against its run at half the step
        sim, error = doubling(count, checked_s, math.inf, 0.0, step)
        expected = prediction.start_error(sim.dt, checked_s)
        predicted = prediction.confirmed(error, sim.dt, checked_s, margin * tolerance, longer)
        if math.isfinite(predicted):
            told = prediction.describe()
            reason += (f'; {told}' if told else '') + (
                f'; {expected:.2%} predicted over the first {checked_s:.2g} s')
            return sim, PilotReport(predicted, math.nan, checked_s, BY_ITSELF, (), 'full', 1.0,
                                    reason=reason, horizon_s=horizon_s, window_error=error,
                                    tolerance=tolerance, predicted=True,
                                    head_start=head_start(stepped, sim))
        reason += (f'; the prediction missed over the first {checked_s:.2g} s ({error:.2%} '
                   f'measured, {expected:.2%} predicted, '
                   f'{prediction.run_error(error, sim.dt, checked_s):.2%} over the run with its '
                   'excess grown): the step was measured instead')
        beyond = prediction.beyond(error, sim.dt, checked_s, margin * tolerance)
        if count < samples and (longer or prediction.leaves_modes_out):
            # a start measured alone, of a longer step or where the prediction left modes out:
            # the run's error is the modes' prediction plus what the start measured beyond it,
            # grown over the run
            grown = prediction
    over_s = horizon_s if count == samples else checked_s
    allowed = margin * tolerance

    def over_run(start_error: float, dt: float) -> float:
        return grown.run_error(start_error, dt, checked_s) if grown else start_error

    # a step longer than the default is measured as it is, never halved: its half is below
    # the default step, which a user would have run in any case (nor where the start's error
    # is grown over the run: the halving judges the start's alone)
    halving = 0.0 if longer or grown else math.inf
    sim, error = doubling(count, over_s, allowed, halving, step)
    if over_run(error, sim.dt) > allowed and longer:
        # a start's transient can miss where the run would not: the default step, its error
        # the longer step's scaled by the step error's order (nothing stepped again) where
        # that is within the margin, else checked by its own step doubling
        checked = full(default_dt, sample_s)
        scaled = error * (checked.dt / sim.dt) ** STEP_ORDER
        reason += (f'; the longer step missed over the start ({error:.2%} against its run at '
                   'half the step): the default step')
        # (not where colliders are, nor far beyond the modes: no smooth motion scales so)
        if (over_run(scaled, checked.dt) <= allowed and checked.model.scene.contact is None
                and not beyond):
            reason += (", its error that one scaled by the square of the steps' ratio "
                       f'({scaled:.2%})')
            sim, error = checked, scaled
        else:
            reason += ' was checked'
            sim, error = doubling(count, over_s, allowed, 0.0 if grown else math.inf,
                                  default_dt)

    def unmeasured(why: str) -> tuple[Simulation, PilotReport]:
        # the run a user would have run, its error not measured, said why
        run = full(default_dt, sample_s)
        return run, PilotReport(
            math.nan, math.nan, checked_s, BY_ITSELF, (), 'full', 1.0, reason=reason,
            horizon_s=horizon_s, window_error=error if math.isfinite(error) else math.nan,
            tolerance=tolerance, unmeasured=why, head_start=head_start(stepped, run))

    missed = sim.dt < checked.dt * (1.0 - 1e-9) or over_run(error, sim.dt) > allowed
    if count < samples and not missed and (beyond or checked.model.scene.contact is not None):
        # far beyond the modes, or a start that sees none of the touches to come: no measure
        reason += f'; the start met the tolerance ({error:.2%} over the first {checked_s:.2g} s)'
        return unmeasured(BEYOND_LINEAR if nonlinear else BEYOND_MODES if beyond
                          else TOUCHES_UNSEEN)
    if missed and count < samples:
        # a twin moved by a hair, at the default step: the motion's growth is the motion's, not
        # the step's, and the halved step the check ended on cost twice as much for it
        at_default = functools.partial(full, default_dt, sample_s)
        growth = start_growth(at_default)
        budget.charge(at_default(), 2.0 * TWIN_S)
        reason += f'; the step missed the tolerance over the first {checked_s:.2g} s'
        if amplifies(growth):     # no step converges: none is sought
            reason += f', and {describe_rate(growth)} over the first {TWIN_S:g} s'
            return unmeasured(AMPLIFYING)
        reason += ': the step needed was sought over the whole window, beyond the budget'
        # at most what the run costs at its default step, or ``SEARCH_FLOOR_US``
        run_us = max(horizon_s * work_per_second(at_default()), SEARCH_FLOOR_US)
        sim, error = doubling(samples, horizon_s, allowed, run_us / window_s, sim.dt)
        checked_s, over_s, grown = window_s, horizon_s, None
        if allowed < error < math.inf:
            reason += (f', and not found at what the run itself costs ({error:.2%} at '
                       f'{sim.dt:.3g} s)')
            return unmeasured(NOT_FOUND)
    if math.isinf(error):       # halving brings nothing, or a run diverged
        return unmeasured(UNCONVERGED)
    run_error = over_run(error, sim.dt)
    if grown:
        reason += (f"; over the {horizon_s:.3g} s run, the modes' prediction and what the start "
                   f'measured beyond it, grown {grown.start_growth(checked_s, sim.dt):.2g} times')
        over_s = horizon_s
    if prediction is not None:
        reason += (f'; {prediction.error_at(sim.dt):.2%} predicted over the {horizon_s:.3g} s '
                   'run (the modes stepped with their period error)')
    return sim, PilotReport(run_error, math.nan, checked_s, BY_ITSELF, (), 'full', 1.0,
                            reason=reason, horizon_s=over_s, window_error=error,
                            tolerance=tolerance, head_start=head_start(stepped, sim))
