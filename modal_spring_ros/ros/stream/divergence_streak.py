"""
Divergences in a row, and the hold they end in.

A divergence is recovered from by going back to rest. The same input again and again (a pose,
a click, a setting) would then loop through divergences forever: after ``MAX_RECOVERIES`` in a
row (each within ``HEALTHY_S`` of simulated time after the recovery before it) the run is held
at rest instead, said once, and inputs are refused until ``~/reset`` clears the hold.
"""
from __future__ import annotations

from modal_spring_ros.core.simulations import DivergenceError

#: divergences in a row that hold the run, and the simulated time that ends a streak, s
MAX_RECOVERIES, HEALTHY_S = 3, 2.0


class HeldError(RuntimeError):
    """An input refused because the run is held after repeated divergence."""


class DivergenceStreak:
    """Counts divergences in a row; ``held`` says why the run is held ('' while it is not)."""

    def __init__(self):
        self.count = 0
        self.held = ''

    def diverged(self, exc: DivergenceError) -> bool:
        """Count a divergence (at ``exc.time`` after the last recovery); True when it holds."""
        self.count = self.count + 1 if exc.time < HEALTHY_S else 1
        if self.count >= MAX_RECOVERIES:
            self.held = (f'{self.count} divergences in a row (last: {exc}): holding at rest, '
                         'inputs refused until ~/reset')
        return bool(self.held)

    def refuse_while_held(self) -> None:
        """
        Refuse an input while the run is held.

        :raises HeldError: the run is held.
        """
        if self.held:
            raise HeldError(f'refused: {self.held}')

    def clear(self) -> None:
        """``~/reset``: no streak, no hold."""
        self.count, self.held = 0, ''
