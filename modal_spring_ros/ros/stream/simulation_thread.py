"""
The node's simulation thread.

Steps at a fixed ``dt``, publishes on its own period, applies state changes between steps, and
survives anything a step or a change can raise. It alone changes the running simulation: requests
(:mod:`modal_spring_ros.ros.changes.requests`) are applied one at a time between two steps, in the
order they came, each by its handler (:mod:`~modal_spring_ros.ros.stream.request_handling`, to
which the thread is a :class:`~modal_spring_ros.ros.stream.request_handling.RunHost`). The thread
is supervised: a divergence sends the run back to rest; any other exception is reported as ERROR
on ``/diagnostics`` with its message, the run goes back to rest (or, if it cannot even reset, to
a simulation rebuilt from the settings), and it goes on.
"""
from __future__ import annotations

import queue
import threading
import time
from typing import Callable

from modal_spring_ros.bags.messages.pointcloud import CloudBuffer
from modal_spring_ros.core.simulations import DivergenceError, Simulation
from modal_spring_ros.core.threads import stepping_threads
from modal_spring_ros.ros.changes.requests import (drained, Request, StepRefused,
                                                   without_superseded)
from modal_spring_ros.ros.stream.diagnostics import StreamReport
from modal_spring_ros.ros.stream.divergence_streak import DivergenceStreak, HeldError
from modal_spring_ros.ros.stream.outputs import Outputs
from modal_spring_ros.ros.stream.plan_watch import FallBack, PlanWatch
from modal_spring_ros.ros.stream.request_handling import apply_request
from modal_spring_ros.ros.stream.run_pace import Reading, RunPace, wall_pace
from modal_spring_ros.ros.stream.stream_book import StreamBook
from modal_spring_ros.ros.stream.stream_settings import StreamSettings

#: wall time between two diagnostics messages, s
DIAGNOSTICS_PERIOD_S = 1.0
#: wait before trying again when even recovering failed, s
RECOVERY_RETRY_S = 0.5
#: share of the publish period left before a frame when the watch's shadows stop (plan_watch)
FRAME_MARGIN = 0.25
#: share of the publish period a frame's steps may take after it is due (a run that cannot keep
#: up drops its debt beyond one frame: its frames keep their rate, its real-time factor falls)
FRAME_LATENESS = 0.75


class SimulationThread:
    """Steps ``sim`` and publishes through ``outputs``; :meth:`submit` changes it."""

    def __init__(self, sim: Simulation, outputs: Outputs,
                 settings: Callable[[], StreamSettings],
                 rebuild: Callable[[], Simulation],
                 computing_modes: Callable[[], bool] = lambda: False,
                 running: Callable[[], bool] = lambda: True,
                 node_report: Callable[[], dict] = dict,
                 on_watch_beyond: FallBack = lambda window, settings: None,
                 pace: Callable[[], Reading] = wall_pace):
        """
        Step ``sim`` and publish through ``outputs`` with the ``settings`` of the moment.

        ``rebuild``: a fresh run of the current settings at rest (recovery's last resort);
        ``computing_modes``: whether a request computes modes now; ``running``: False once the
        node shuts down (the thread then ends instead of reporting its publishers gone);
        ``node_report``: the node's :class:`StreamReport` fields; ``on_watch_beyond``: falls an
        automatic plan back (:mod:`~.plan_watch`); ``pace``: the clock it keeps pace with.
        """
        self._running = running
        self._node_report = node_report
        self.sim = sim
        self.paused = False
        self._suspended = False  # a managed node inactive: no steps, no frames
        self.outputs = outputs
        self.settings = settings
        self._rebuild = rebuild
        self._requests: queue.Queue[Request] = queue.Queue()
        self._stop = threading.Event()
        self._wake = threading.Event()  # the settings changed: stop waiting out the old period
        self.book = StreamBook(sim.status(), computing_modes)
        self._cloud: CloudBuffer | None = None  # the frames' bytes, reused (see _publish_frame)
        self._cloud_scene = None
        self.streak = DivergenceStreak()
        self._pace = RunPace(pace, sim.time)
        self.plan_watch = PlanWatch(on_watch_beyond)
        self._thread = threading.Thread(target=self._run, name='modal_spring_sim', daemon=True)

    # -- from other threads --------------------------------------------------------------------
    def start(self) -> None:
        self._thread.start()

    def submit(self, request: Request) -> Request:
        """Queue a state change; the thread applies it between two steps."""
        self._requests.put(request)
        return request

    def settings_changed(self) -> None:
        """
        Make the thread read its settings now.

        A new publish rate then takes effect at once instead of after the old period (0.1 Hz
        to 60 Hz once meant ten seconds without a frame).
        """
        self._wake.set()

    def stop(self, timeout: float = 5.0) -> None:
        self._stop.set()
        self._wake.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout)
        self._fail_pending('the node is shutting down')

    def suspend(self) -> None:
        """Stop stepping and publishing frames until :meth:`resume` (diagnostics go on)."""
        self._suspended = True

    def resume(self) -> None:
        """Step and publish again, from where the run was (its time does not jump)."""
        self.reanchor(window_valid=False)
        self._suspended = False
        self._wake.set()

    @property
    def alive(self) -> bool:
        return self._thread.is_alive()

    # -- the thread ----------------------------------------------------------------------------
    def _active(self) -> bool:
        return not self._stop.is_set() and self._running()

    @stepping_threads()         # steps and frames on one BLAS thread (core.threads)
    def _run(self) -> None:
        while self._active():
            try:
                self._loop()
            except Exception as exc:  # supervised: report, recover, go on
                if not self._active():
                    return
                self._recover(f'simulation thread failed: {exc!r}')

    def _loop(self) -> None:
        next_publish = next_mesh = time.monotonic()
        next_diagnostics = next_publish + DIAGNOSTICS_PERIOD_S
        self._start_window(valid=True)
        published_time = None
        period = None
        while self._active():
            settings = self.settings()
            if period != 1.0 / settings.publish_rate_hz:  # a new rate counts from now
                period = 1.0 / settings.publish_rate_hz
                next_publish = min(next_publish, time.monotonic() + period)
            rtf = settings.realtime_factor
            if self._apply_requests():
                published_time = None
            behind = False
            still = self.paused or self.held or self._suspended
            if not still:
                if rtf > 0.0:
                    target, jumped = self._pace.owed(self.sim.time, rtf)
                    if jumped:
                        self._start_window(valid=False)
                    self.step_until(target, next_publish + FRAME_LATENESS * period)
                    behind = self.sim.time + self.sim.dt < target
                    if target - self.sim.time > rtf * period:  # could not keep up: the debt
                        # beyond one frame's steps is dropped (the frames keep their rate)
                        self._pace.anchor(self.sim.time + rtf * period, at_last_reading=True)
                else:  # as fast as possible: as many steps as fit until the frame is due
                    self.step_until(float('inf'), next_publish)
            now = time.monotonic()
            # woken before the frame is due (a setting changed): the frame stays on its grid
            due = now >= next_publish
            # a held run goes on publishing its held state: the stream never goes silent
            if due and (self.sim.time != published_time or self.held) and not (
                    self.paused or self._suspended):
                mesh = now >= next_mesh and settings.mesh_rate_hz > 0
                self.publish_frame(mesh)
                published_time = self.sim.time
                if mesh:
                    next_mesh = now + 1.0 / settings.mesh_rate_hz
            if now >= next_diagnostics or self.book.report_due():   # modes begun or ready
                self._publish_diagnostics(settings, error=self.held)
                next_diagnostics = now + DIAGNOSTICS_PERIOD_S
            if due:
                next_publish += period
                if next_publish < now:
                    next_publish = now + period
            if not still:   # in the idle time before the next frame (behind: one sample)
                self.plan_watch.step(self.sim, settings.watch_s,
                                     next_publish - FRAME_MARGIN * period)
            if (rtf > 0.0 and not behind) or still:   # behind: step on towards the next frame
                self._wake.wait(max(0.0, next_publish - time.monotonic()))
                self._wake.clear()

    def step_until(self, target: float, deadline: float) -> None:
        """
        Step until the simulation reaches ``target`` or the wall clock passes ``deadline``.

        The target is reached to half a step; at least one step is taken when the target is ahead.
        """
        sim = self.sim
        while sim.time + 0.5 * sim.dt < target:
            start = time.perf_counter()
            try:
                sim.step()
            except DivergenceError as exc:
                self._on_divergence(exc)
                return
            self.book.stepped(time.perf_counter() - start)
            if time.monotonic() > deadline:
                return

    def _apply_requests(self) -> bool:
        """
        Apply every queued request, in order; True when one was applied.

        One a newer one of its kind directly follows is answered, not applied
        (:func:`~modal_spring_ros.ros.changes.requests.without_superseded`).
        """
        applied = False
        for request in without_superseded(drained(self._requests)):
            try:
                message = apply_request(self, request)
            except (HeldError, StepRefused) as exc:  # said once (held), or not an error
                request.finish(False, str(exc))
                continue
            except Exception as exc:  # refused: the run is as it was before the request
                request.finish(False, f'could not apply: {exc}')
                self._report_error(f'could not apply {type(request).__name__}: {exc!r}')
                continue
            request.finish(True, message)
            applied = True
        return applied

    held = property(lambda self: self.streak.held, doc='Why the run is held, or empty.')

    def _fail_pending(self, why: str) -> None:
        for request in drained(self._requests):
            request.finish(False, why)

    # -- frames and reports --------------------------------------------------------------------
    def publish_frame(self, mesh: bool) -> None:
        scene = self.sim.model.scene
        if self._cloud is None or self._cloud_scene is not scene:  # once per scene
            self._cloud, self._cloud_scene = CloudBuffer(scene.rest_positions), scene
        self._cloud.write_run(self.sim)  # in place: no array per frame
        if not self._cloud.finite():  # defensive: the engine never returns these
            self._on_divergence(DivergenceError('non-finite positions', self.sim.time,
                                                self.sim.steps))
            return
        self.outputs.frame(self.sim, self._cloud, mesh)
        self.book.framed()

    def _report(self, settings: StreamSettings, error: str = '') -> StreamReport:
        return self.book.report(
            self.sim.time, self._pace.since(self.book.window.pace),  # the clock the run follows
            requested_rtf=settings.realtime_factor,
            publish_period_s=1.0 / settings.publish_rate_hz,
            paused=self.paused, strain_warning=settings.strain_warning, error=error,
            **self.plan_watch.report(), **self._node_report())

    def _publish_diagnostics(self, settings: StreamSettings, error: str = '') -> None:
        self.outputs.diagnostics(self.book.status(self.sim), self._report(settings, error))
        self._start_window(valid=True)
        if not error:
            self.book.diverged_recently = False

    def _start_window(self, valid: bool) -> None:
        self.book.open_window(self.sim.time, valid, self._pace.read())

    def reanchor(self, window_valid: bool) -> None:
        self._pace.anchor(self.sim.time)
        if not window_valid:
            self.book.invalidate()

    # -- failures ------------------------------------------------------------------------------
    def _on_divergence(self, exc: DivergenceError) -> None:
        self.book.diverged(str(exc))
        if self.streak.diverged(exc):
            self.outputs.log('error', self.held)
            self._publish_diagnostics(self.settings(), error=self.held)
        else:
            self.outputs.log('error', f'{exc}; back to the rest state')
            self._publish_diagnostics(self.settings(),
                                      error=f'{exc}; recovered: back to the rest state')
        self._to_rest()

    def _report_error(self, message: str) -> None:
        """Log and publish ERROR; never raises (it is what failures end in)."""
        try:
            self.outputs.log('error', message)
            self.outputs.diagnostics(self.book.last_status,
                                     self._report(self.settings(), message))
        except Exception as exc:  # publishing itself failed (shutting down): log only
            try:
                self.outputs.log('error', f'{message} (not reported: {exc!r})')
            except Exception:
                pass

    def _recover(self, message: str) -> None:
        self._report_error(f'{message}; recovered: back to the rest state')
        if not self._to_rest():
            self._stop.wait(RECOVERY_RETRY_S)

    def _to_rest(self) -> bool:
        """Reset; if the simulation cannot, continue with a rebuilt one. False if both fail."""
        try:
            self.sim.reset()
        except Exception as exc:
            self._report_error(f'reset failed: {exc!r}; rebuilding the simulation')
            try:
                self.sim = self._rebuild()
            except Exception as again:
                self._report_error(f'rebuilding the simulation failed: {again!r}')
                return False
        self.plan_watch.restart()
        self.reanchor(window_valid=False)
        return True
