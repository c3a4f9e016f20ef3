"""
A recorded run as arrays, and its ``.npz`` file: everything needed to re-check it independently.

Fields (``F`` frames, ``n`` particles, ``E`` springs): ``t`` (F,), ``positions`` (F, n, 3) float64,
``rest_positions`` (n, 3), ``springs`` (E, 2) int, ``stiffness`` (E,), ``rest_length`` (E,),
``mass`` (n,), ``fixed`` (n,) bool, ``gravity`` (3,), ``damping_ratio`` (scalar h, 0 if unused),
``rayleigh_alpha``, ``rayleigh_beta``, ``frequencies_hz`` (the computed modes, ascending),
``kept_modes`` (indices in the last step), ``dt``; plus ``method``, ``integrator``, ``band``
(text), ``scene_archive`` (the full scene: the bytes of an ``.npz`` archive of its arrays,
:mod:`~modal_spring_ros.scenes.files.scene_archive`; runs written before it hold ``scene_yaml``,
its YAML text) and ``diverged`` (empty, or the divergence message).
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
import time
from typing import Callable

from modal_spring_ros.core.auto.watch.run_watch import RunWatch, WatchedWindow
from modal_spring_ros.core.model.scene import Scene
from modal_spring_ros.core.simulations import DivergenceError, Simulation
from modal_spring_ros.core.threads import stepping_threads
from modal_spring_ros.runs.frame_store import frame_count, FrameStore, IN_MEMORY_BYTES
from modal_spring_ros.scenes.files.scene_archive import scene_to_archive
import numpy as np

#: least wall time between two progress reports of :func:`record`, s (a short run reports none)
PROGRESS_INTERVAL_S = 1.0


@dataclasses.dataclass
class Run:
    scene: Scene
    t: np.ndarray
    positions: np.ndarray
    frequencies_hz: np.ndarray
    kept_modes: np.ndarray
    dt: float
    method: str
    integrator: str
    band: str
    diverged: str = ''
    #: frames made (those in ``t`` and ``positions``, or more where only the last was kept)
    frames_made: int = 0
    #: the simulation the run ended on (not saved: a watched run may have fallen back)
    simulation: Simulation | None = dataclasses.field(default=None, repr=False, compare=False)

    @property
    def compressed(self) -> bool:
        """Tell whether :meth:`save_npz` compresses the run (its frames fit in memory)."""
        return self.positions.nbytes <= IN_MEMORY_BYTES

    def save_npz(self, path: str | Path) -> None:
        """
        Write the run to ``path`` (``.npz``, compressed where its frames are few).

        Frames beyond what memory should hold (``IN_MEMORY_BYTES``) are stored uncompressed:
        streamed from where they are kept, as a run's positions compress by a few percent at
        about 20 MB/s (a 1.3 GB run: 8 % smaller after a minute).
        """
        s = self.scene
        save = np.savez_compressed if self.compressed else np.savez
        path = Path(path)
        with open(path, 'wb') as fh:  # np.savez would append ".npz" to other names
            save(fh, t=self.t, positions=np.asarray(self.positions, dtype=np.float64),
                 rest_positions=s.rest_positions, springs=s.springs, stiffness=s.stiffness,
                 rest_length=s.rest_length, mass=s.mass, fixed=s.fixed, gravity=s.gravity,
                 damping_ratio=s.damping.ratio, rayleigh_alpha=s.damping.rayleigh_alpha,
                 rayleigh_beta=s.damping.rayleigh_beta, frequencies_hz=self.frequencies_hz,
                 kept_modes=self.kept_modes, dt=self.dt, method=self.method,
                 integrator=self.integrator, band=self.band,
                 scene_archive=np.frombuffer(scene_to_archive(s), dtype=np.uint8),
                 diverged=self.diverged)


@stepping_threads()         # steps and frames on one BLAS thread (core.threads)
def record(sim: Simulation, duration: float, *, frame_every: int = 1,
           on_progress: Callable[[float], None] | None = None,
           on_frame: Callable[[float, np.ndarray], None] | None = None,
           progress_interval_s: float = PROGRESS_INTERVAL_S,
           watch: RunWatch | None = None,
           on_watch: Callable[[WatchedWindow, Simulation], None] | None = None,
           keep_frames: bool = True, frames_dir: str | Path | None = None) -> Run:
    """
    Step ``sim`` for ``duration`` seconds.

    Keeping a frame (t = 0 included) every ``frame_every`` steps. Stops at a divergence and records
    its message (no bad frame). ``on_frame(t, positions)`` sees every frame as it is made (e.g. to
    stream it to a bag). ``on_progress(fraction done)`` is called at whole percents, at most once
    per ``progress_interval_s`` of wall time.

    With ``watch`` (:mod:`~modal_spring_ros.core.auto.watch.run_watch`), the plan's error is
    measured again from the run's state every watch interval; ``on_watch(window, simulation)``
    sees each window and the simulation that goes on (the fallback, where the window was beyond the
    tolerance: the run continues as it from the window's start, at a step that divides the frame
    interval). The run's :attr:`Run.simulation` is the one it ended on.

    Not ``keep_frames``: only the last frame is kept (``on_frame`` still sees each; without it,
    no other frame is made): a run whose frames go to a bag or nowhere holds one frame, not
    every one (the 10k sheet over 10 s at every step would hold 21 GB). Frames kept are held
    once (:class:`~modal_spring_ros.runs.frame_store.FrameStore`): beyond what memory should
    hold, in a file in ``frames_dir`` (None: the system's temporary folder).
    """
    frame_s = frame_every * sim.dt
    steps = int(round(duration / sim.dt))
    start = sim.time
    end = start + steps * sim.dt
    store = FrameStore(frame_count(end - start, sim.dt, frame_every) if keep_frames else 1,
                       sim.model.scene.n_particles, frames_dir)
    first = sim.positions()
    store.append(sim.time, first)
    if on_frame:
        on_frame(sim.time, first)
    diverged = ''
    check_every = max(1, steps // 100)
    last_report = time.monotonic()
    next_frame = sim.time + frame_s
    k, made = 0, 1
    while sim.time + 0.5 * sim.dt < end:
        if watch is not None:
            sim, window = watch.before_step(sim, frame_s)
            if window is not None:
                if not window.within:             # the fallback watched by its twin, or not
                    watch = watch.after_fallback(sim)
                if on_watch:
                    on_watch(window, sim)
        try:
            sim.step()
        except DivergenceError as exc:
            diverged = str(exc)
            break
        k += 1
        if sim.time >= next_frame - 0.5 * sim.dt:
            next_frame += frame_s
            made += 1
            if keep_frames or on_frame:
                if not keep_frames:
                    store.clear()
                frame = sim.positions()
                store.append(sim.time, frame)
                if on_frame:
                    on_frame(sim.time, frame)
        if on_progress and k % check_every == 0:
            now = time.monotonic()
            if now - last_report >= progress_interval_s:
                on_progress(min(1.0, (sim.time - start) / (end - start)))
                last_report = now
    if watch is not None and not diverged:       # a twin's window that ends with the run
        window = watch.after_run(sim)
        if window is not None and on_watch:
            on_watch(window, sim)
    if not (keep_frames or on_frame):            # no frame was made but the last
        store.clear()
        store.append(sim.time, sim.positions())
    freqs = sim.basis.frequencies_hz if sim.basis is not None else np.empty(0)
    kept, band = sim.kept_modes, sim.describe_band()
    return Run(scene=sim.model.scene, t=store.times, positions=store.positions,
               frequencies_hz=freqs, kept_modes=np.asarray(kept, dtype=np.int64), dt=sim.dt,
               method=sim.method, integrator=sim.integrator, band=band, diverged=diverged,
               frames_made=made, simulation=sim)
