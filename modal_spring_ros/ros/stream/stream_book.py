"""
What the simulation thread counts for ``/diagnostics``: its windows, frames and divergences.

The thread steps and publishes; a :class:`StreamBook` keeps the numbers that become its
:class:`~modal_spring_ros.ros.stream.diagnostics.StreamReport`: one window a diagnostics
period (wall and simulated time at its start, steps and their wall time, frames, the longest
gap between two), the frames and divergences since the start, the last simulation status read,
and whether modes were being computed when the last report went out (a change of that is
reported at once, not a period later, as diagnostic_updater's ``force_update`` does). Only the
simulation thread writes it.
"""
from __future__ import annotations

import time
from typing import Any, Callable

from modal_spring_ros.core.simulations import Simulation, SimulationStatus
from modal_spring_ros.ros.stream.diagnostics import StreamReport, StreamWindow


class StreamBook:
    """The simulation thread's counts, turned into a stream report on demand."""

    def __init__(self, status: SimulationStatus, computing_modes: Callable[[], bool]):
        """Start with the run's first ``status``; ``computing_modes`` says whether modes are."""
        self.window = StreamWindow()
        self.frames = 0
        self.divergences = 0
        self.last_divergence = ''
        self.diverged_recently = False
        self.last_status = status
        self._computing_modes = computing_modes
        self._last_frame = 0.0
        self._reported_computing = False

    def open_window(self, sim_time: float, valid: bool, pace: tuple[str, float]) -> None:
        """Start a window at ``sim_time``; not ``valid`` when the run jumped inside it."""
        self.window = StreamWindow(time.monotonic(), sim_time, valid, pace=pace,
                                   computing_modes=self._computing_modes())
        self._last_frame = 0.0

    def invalidate(self) -> None:
        """Say the run jumped (reset, pause, a new run): no rate and no gap over the jump."""
        self.window.valid = False
        self._last_frame = 0.0

    def stepped(self, seconds: float) -> None:
        """Count one step that took ``seconds`` of wall time."""
        self.window.step_seconds += seconds
        self.window.steps += 1

    def framed(self) -> None:
        """Count a frame published now."""
        now, w = time.monotonic(), self.window
        if self._last_frame:
            w.longest_gap = max(w.longest_gap, now - self._last_frame)
        self._last_frame = now
        self.frames += 1
        w.frames += 1
        w.computing_modes |= self._computing_modes()

    def frame_after_pause(self) -> None:
        """Say the next frame follows a pause: no gap is counted before it."""
        self._last_frame = 0.0

    def diverged(self, message: str) -> None:
        """Count a divergence."""
        self.divergences += 1
        self.last_divergence = message
        self.diverged_recently = True

    def report_due(self) -> bool:
        """Tell whether modes began or ceased being computed since the last report."""
        return self._computing_modes() != self._reported_computing

    def status(self, sim: Simulation) -> SimulationStatus:
        """Return the run's status, or the last one read when it cannot give one."""
        try:
            self.last_status = sim.status()
        except Exception:  # reported by whoever called; the last good status stands in
            pass
        return self.last_status

    def report(self, sim_time: float, pace_since: tuple[float, bool],
               **fields: Any) -> StreamReport:
        """
        Return the report of the window up to ``sim_time``.

        ``pace_since``: the span of the paced clock since the window began and whether it
        stood still; ``fields``: the report's other fields (settings, the node's, the watch's).
        """
        w = self.window
        clock_span, clock_stopped = pace_since
        achieved = (sim_time - w.sim_time) / clock_span if clock_span > 0 else 0.0
        computing = self._computing_modes()
        self._reported_computing = computing
        return StreamReport(
            window_s=time.monotonic() - w.wall, window_valid=w.valid, clock_stopped=clock_stopped,
            achieved_rtf=achieved if w.valid else 0.0,
            step_us=1e6 * w.step_seconds / max(w.steps, 1), frames=self.frames,
            frames_in_window=w.frames, longest_gap_s=w.longest_gap,
            computing_modes=w.computing_modes or computing, divergences=self.divergences,
            last_divergence=self.last_divergence, diverged_recently=self.diverged_recently,
            **fields)
