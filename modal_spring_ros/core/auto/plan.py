"""
An automatic plan (what it sets) and what its pilot run measured about it.

:class:`PlanSettings` is what :mod:`~modal_spring_ros.core.auto.pilot` refines;
:class:`PilotReport` is what it found, printed in the summary and on ``/diagnostics``, and
where a full run's error is not measured, why (``UNCONVERGED``, ``NOT_FOUND``, ``AMPLIFYING``,
``BEYOND_MODES``, ``BEYOND_LINEAR``, ``TOUCHES_UNSEEN``).
"""
from __future__ import annotations

import dataclasses
import math

from modal_spring_ros.core.simulations.run_state import RunState

#: What a run whose error is not measured takes, in each reason's words.
_DEFAULT_STEP = "the default step, as '--method full' runs it"
#: Why a run whose error does not shrink as its step is halved has none measured.
UNCONVERGED = ('its runs do not converge as the step is halved: the motion amplifies its '
               "differences (buckling, large strain, chaos), so no step's error over the run "
               f'can be promised; {_DEFAULT_STEP}')
#: Why a run whose step the whole window's search did not find has no error measured.
NOT_FOUND = ('halving its step over the whole window found none within the tolerance at what '
             f'the run itself costs; {_DEFAULT_STEP}')
#: Why a run whose start amplifies a hair's difference has no error measured.
AMPLIFYING = ('its motion amplifies its differences from its start (chaotic): no step keeps '
              f'within the tolerance of another for long; {_DEFAULT_STEP}')
#: Why a run with colliders whose start alone the budget checked has no error measured.
TOUCHES_UNSEEN = ('the scene has colliders and its start sees none of the touches to come, '
                  'while checking the whole window (its run at half the step, twice the run) '
                  "would cost more than the planning budget ('--planning-share none' checks "
                  f'it); {_DEFAULT_STEP}')
#: Why a run whose modes' motion is no small displacement has no error measured.
BEYOND_LINEAR = ("its modes' motion moves springs' ends apart by their own length or more (large "
                 "deformation): no step's error is predicted from them, and its start says "
                 'nothing of the rest of the run, which would cost more to check than to run; '
                 f'{_DEFAULT_STEP}')
#: Why a run whose start moved far beyond its modes' prediction has no error measured.
BEYOND_MODES = ('its start moved far beyond what its modes predict, and says nothing of the '
                f'rest of the run, which would cost more to check than to run; {_DEFAULT_STEP}')


@dataclasses.dataclass(frozen=True)
class PlanSettings:
    """What an automatic plan sets: modes (up to ``highest_hz``), basis, forces, step."""

    highest_hz: float
    basis_kind: str
    directions: int
    forces: str
    refresh: int
    dt: float

    def describe(self) -> str:
        forces = (f'springs every {self.refresh} steps' if self.forces == 'refreshed'
                  else f'{self.forces} forces')
        basis = (f'derivatives basis ({self.directions} directions)'
                 if self.basis_kind == 'derivatives' else 'rest modes')
        return f'modes up to {self.highest_hz:.4g} Hz, {basis}, {forces}, dt {self.dt:.3g} s'


@dataclasses.dataclass(frozen=True)
class PilotReport:
    """What the pilot measured, against what, and what it chose."""

    error: float                    # relative error of the chosen plan over the horizon
    planned_error: float            # the same for the plan as first predicted
    window_s: float
    against: str                    # 'the full run', 'a richer plan' (and the full run's
    #                                 start, where checked) or (full) BY_ITSELF
    refined: tuple[str, ...]        # refinements applied, in order
    method: str                     # 'modal' or 'full'
    cost_ratio: float               # the plan's cost per simulated second / the full run's
    reason: str = ''                # why the full run was chosen, when it was
    horizon_s: float = 0.0          # the run the promise is for, s (0: the window)
    window_error: float = math.nan  # the chosen plan's error measured over the window
    tolerance: float = math.nan     # what the plan was to meet
    planning: str = ''              # what planning spent of its budget
    predicted: bool = False         # error predicted over the horizon, checked over the window
    unmeasured: str = ''            # why the error is not measured, where it is not finite
    #: the chosen run's state where the pilot's own run of it ended (a run that records
    #: nothing before may go on from there: :func:`~.full_candidate.head_start`)
    head_start: RunState | None = dataclasses.field(default=None, compare=False, repr=False)

    def _over(self) -> str:
        """Say how the error was found: measured over the window, extrapolated beyond."""
        if self.predicted:
            return (f'predicted over a {self.horizon_s:.3g} s run (the modes stepped with the '
                    f"step's period error; the prediction held where measured: "
                    f'{self.window_error:.2%} against {self.against} over the first '
                    f'{self.window_s:.3g} s)')
        if self.horizon_s <= self.window_s * (1.0 + 1e-9):
            return f'against {self.against} over {self.window_s:.3g} s (pilot)'
        return (f'over a {self.horizon_s:.3g} s run (measured {self.window_error:.2%} against '
                f'{self.against} over {self.window_s:.3g} s, drift extrapolated)')

    def as_checked(self, checked: 'PilotReport | None') -> 'PilotReport':
        """Return this report with how ``checked`` (the full run's own check) found its error."""
        if checked is None:
            return self
        return dataclasses.replace(self, window_s=checked.window_s, horizon_s=checked.horizon_s,
                                   window_error=checked.window_error, predicted=checked.predicted,
                                   head_start=(self.head_start if checked.head_start is None
                                               else checked.head_start))

    def _unmeasured(self) -> str:
        """Say why the error is not measured (it is not finite)."""
        if self.unmeasured:
            return self.unmeasured
        return ('its runs did not converge as its step was halved' if math.isinf(self.error)
                else 'no check within the planning budget')

    def describe(self) -> str:
        spent = f'; {self.planning}' if self.planning else ''
        if self.method == 'full':
            beyond = (f'; NOT within {self.tolerance:.2%}: the full run did not converge to it '
                      f'at any step the pilot could afford' if self.error > self.tolerance
                      else '')
            error = (f'error {self.error:.2%} {self._over()}' if math.isfinite(self.error)
                     else f'its step error not measured ({self._unmeasured()})')
            first = (f'; the modal plan as first made: {self.planned_error:.2%}'
                     if math.isfinite(self.planned_error) else '')
            return f'full run chosen ({self.reason}): {error}{first}{beyond}{spent}'
        steps = f", refined: {', '.join(self.refined)}" if self.refined else ''
        return (f'measured error {self.error:.2%} {self._over()}{steps}; work '
                f'{self.cost_ratio:.2g} x the full run{spent}')
