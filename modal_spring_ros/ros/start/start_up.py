"""
The node's first frames on a large scene: streaming while its spring sample is trained.

``modal.forces`` ``sampled`` trains a sample of the springs before the run can use it: a run of
the scene with every spring for snapshots, then the fit (about 3 s on ``sheet_100x100``, and
over a minute of CPU on ``sheet_316x316``, beside the modes). A node that waited for it would
show nothing meanwhile. On scenes of :data:`STAGED_SPRINGS` springs and more the node starts
instead with the springs refreshed every few steps (``modal.forces`` ``refreshed``: every spring
evaluated every ``modal.force_refresh`` steps, their tangent between, accurate in small
deformation), and asks its change preparer for the sampled forces as its first change: the
sample is trained in the worker process while the stream runs, ``/diagnostics`` says
``preparing modal.forces='sampled'`` meanwhile, and the run takes the sample, its state carried
over, once it is ready (at once where the sample cache has it). ``modal.forces`` reads
``sampled`` throughout: what was asked for, and what the run settles on; should the training
fail, the parameter goes back to ``refreshed`` with the reason in the log, as a failed change
does.

Its modes come the same way. On scenes of :data:`STAGED_DOF` free coordinates and more, the
Lanczos iteration for a band's modes costs seconds a mode set (``sheet_316x316``: 8 modes in
3.1 s of CPU, 32 in 9.9 s, beside 2.8 s for the factor they share), so a band that reaches past
the lowest :data:`FIRST_MODES` modes starts on those (``modal.max_modes`` at
:data:`FIRST_MODES`: the band as asked, cut after its first modes), and the rest of the band is
the first change: computed in the worker, whose factor of the stiffness is kept for it, and
taken by the run with its state carried over, as a band that needs more modes is.
``/diagnostics`` says ``parameter changes pending: modal.max_modes=256`` meanwhile, with the
worker's ``progress``; the parameter reads what was asked for throughout.

An automatic plan (``modal.auto``) is measured before it is trusted: a pilot run, seconds on a
small scene and minutes on a large one. Its first frames come from a run that needs no plan:
the full run (an all-pass band: what the plan approximates, and what it falls back to) at its
default step, or the band's own rest modes as asked (a band that filters, or any band of a
scene of :data:`STAGED_DOF` free coordinates and more), staged as above on large scenes. The
plan is the first change, taken over with the state carried over once it is measured
(``method``, ``modal.auto`` and what else differed read what was asked throughout).
``stream_early`` false waits for all of it instead.
"""
from __future__ import annotations

import dataclasses
from typing import Any

from modal_spring_ros.core.config import SAMPLE_MIN_SPRINGS, SimulationConfig
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.model.scene import Scene
from modal_spring_ros.core.simulations import DEFAULT_MAX_MODES
import numpy as np

#: scenes with this many springs or more start before their sample is trained (the size from
#: which the automatic choice samples springs, and training takes seconds)
STAGED_SPRINGS = SAMPLE_MIN_SPRINGS
#: the forces the first frames are stepped with while the sample trains
FIRST_FORCES = 'refreshed'
#: scenes with this many free coordinates or more stream on their lowest modes first
STAGED_DOF = 50_000
#: the modes the first frames of such a scene are stepped with (at most)
FIRST_MODES = 8


def first_values(config: SimulationConfig, scene: Scene) -> dict[str, Any]:
    """
    Return the parameters the first run takes in place of the values asked for (or none).

    A modal run starts with refreshed springs where it asked for sampled ones on a scene of
    :data:`STAGED_SPRINGS` springs or more, and on its lowest :data:`FIRST_MODES` modes where
    its band needs more of a scene of :data:`STAGED_DOF` free coordinates or more. An automatic
    plan starts with the full run (an all-pass band) or the band's rest modes, as asked
    otherwise (:func:`before_the_plan`).
    """
    if config.method != 'modal':
        return {}
    if config.auto:
        return before_the_plan(config, scene)
    first: dict[str, Any] = {}
    if config.forces == 'sampled' and scene.n_springs >= STAGED_SPRINGS:
        first['modal.forces'] = FIRST_FORCES
    if (scene.n_free_dof >= STAGED_DOF and (config.max_modes or DEFAULT_MAX_MODES) > FIRST_MODES
            and _starts_low(config.band)):
        first['modal.max_modes'] = FIRST_MODES
    return first


def before_the_plan(config: SimulationConfig, scene: Scene) -> dict[str, Any]:
    """
    Return what the first run of an automatic plan takes while the plan is measured.

    The full run where the band keeps every mode (what the plan approximates) on a scene below
    :data:`STAGED_DOF` free coordinates; else the band as asked on its rest modes, with the
    first values of such a run (:func:`first_values`: on a huge scene its lowest modes, whose
    stepping leaves the planning the core the full run's would take).
    """
    if config.band.kind == 'allpass' and scene.n_free_dof < STAGED_DOF:
        return {'method': 'full', 'modal.auto': False}
    unplanned = dataclasses.replace(config, auto=False, basis='rest')
    return {'modal.auto': False, 'modal.basis': 'rest', **first_values(unplanned, scene)}


def _starts_low(band: FilterBand) -> bool:
    """
    Tell whether ``band`` surely keeps some of the lowest :data:`FIRST_MODES` modes, and more.

    By index that is known before any mode is; by frequency only a low-pass (or the whole
    spectrum) surely keeps the lowest mode. Gain terms (in Hz) may take any mode out.
    """
    if band.gains:
        return False
    if band.by == 'index':
        kept = band.keeps(np.zeros(FIRST_MODES))     # by index only the modes' count matters
        return bool(kept.any()) and (not band.bounded_above or band.top >= FIRST_MODES)
    return band.kind in ('allpass', 'lowpass')
