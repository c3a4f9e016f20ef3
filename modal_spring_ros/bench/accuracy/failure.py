"""
Where the paper's method fails, and what holds there.

The large-deformation scene (``sheet_10x10_resonance``), rest modes and their derivatives against
the full run, and the turning clamp (``sheet_10x10_swing``) in its floating frame.
"""
from __future__ import annotations

import dataclasses
import math
import time

from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.config import DEFAULT_STRAIN_WARNING
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.motion.anchor_motion import AnchorMotion
from modal_spring_ros.core.simulations import (DivergenceError, FullSimulation, ModalSettings,
                                               ModalSimulation)
from modal_spring_ros.scenes.resources import load_scene
import numpy as np


def failure(progress, duration: float) -> dict:
    """
    Return the large-deformation scene: 15-mode low-pass (paper fig.

    10b) against the full run, with rest modes and with their derivatives: windowed relative error
    over time, and the strain the node watches.
    """
    progress('failure: sheet_10x10_resonance, 15 modes against full')
    model = MassSpringModel(load_scene('sheet_10x10_resonance'))
    basis = ModalBasis(model)
    dt = model.scene.default_dt
    full = FullSimulation(model, dt=dt, basis=basis)
    band = FilterBand('lowpass', 0, 14, 'index')
    modal = ModalSimulation(model, basis, band, ModalSettings(dt=dt))
    derived = ModalSimulation(model, basis, band, ModalSettings(dt=dt, basis_kind='derivatives'))
    window = int(round(0.25 / dt))
    t, err, strain, full_strain, derived_err = [], [], [], [], []
    derived_num = derived_all_num = all_den = 0.0
    diverged_at = None
    num = den = 0.0
    for k in range(1, int(round(duration / dt)) + 1):
        full.step()
        if diverged_at is None:
            try:
                modal.step()
            except DivergenceError:
                diverged_at = modal.time
        derived.step()
        d = modal.displacement() - full.displacement()
        num += float(d @ d)
        den += float(full.displacement() @ full.displacement())
        dd = derived.displacement() - full.displacement()
        derived_num += float(dd @ dd)
        if k % window == 0:
            t.append(full.time)
            err.append(math.sqrt(num / max(den, 1e-300)))
            derived_err.append(math.sqrt(derived_num / max(den, 1e-300)))
            derived_all_num += derived_num
            all_den += den
            derived_num = 0.0
            strain.append(modal.max_strain())
            full_strain.append(full.max_strain())
            num = den = 0.0
    crossing = next((ti for ti, e in zip(t, err) if e > 0.1), None)
    warn = next((ti for ti, s in zip(t, strain) if s > DEFAULT_STRAIN_WARNING), None)
    return {'t': t, 'rel_l2_window': err, 'modal_strain': strain, 'full_strain': full_strain,
            'error_passes_10pct_at': crossing, 'strain_warning_at': warn,
            'strain_warning': DEFAULT_STRAIN_WARNING, 'modal_diverged_at': diverged_at,
            'derivatives_rel_l2_window': derived_err,
            'derivatives_rel_l2': math.sqrt(derived_all_num / max(all_den, 1e-300)),
            'derivatives_coordinates': derived.coordinates}


def turning_clamp(progress, duration: float) -> dict:
    """
    Return the turning clamp (``sheet_10x10_swing``).

    The 15-mode band in the clamp's frame, with the derivatives basis and with rest modes, against
    the full run in the world, and the same band with the turn left out (today's base excitation:
    the clamp's translation only, here none). Windowed relative error of the deformation (the
    displacement in the clamp's frame) and of the world positions, and the cost per step against
    the translating sheet_10x10's.
    """
    progress("failure: sheet_10x10_swing, 15 modes in the clamp's frame against full")
    scene = load_scene('sheet_10x10_swing')
    model = MassSpringModel(scene)
    basis = ModalBasis(model)
    dt = scene.default_dt
    band = FilterBand('lowpass', 0, 14, 'index')
    full = FullSimulation(model, basis, dt=dt)
    runs = {'derivatives': ModalSimulation(model, basis, band,
                                           ModalSettings(dt=dt, basis_kind='derivatives')),
            'rest': ModalSimulation(model, basis, band, ModalSettings(dt=dt, basis_kind='rest'))}
    still = MassSpringModel(dataclasses.replace(scene, anchor_motion=AnchorMotion(())))
    left_out = ModalSimulation(still, ModalBasis(still), band,
                               ModalSettings(dt=dt, basis_kind='derivatives'))
    window = int(round(0.25 / dt))
    names = [*runs, 'turn left out']
    windows = {name: [] for name in names}
    sums = {name: np.zeros(4) for name in names}     # window num, den; run num, den
    t = []
    for k in range(1, int(round(duration / dt)) + 1):
        full.step()
        for sim in (*runs.values(), left_out):
            sim.step()
        f = full.displacement()
        for name, sim in runs.items():
            d = sim.displacement() - f
            sums[name] += [d @ d, f @ f, d @ d, f @ f]
        world = full.positions() - scene.rest_positions
        d = left_out.positions() - full.positions()
        sums['turn left out'] += [np.sum(d * d), np.sum(world * world)] * 2
        if k % window == 0:
            t.append(full.time)
            for name in names:
                windows[name].append(math.sqrt(sums[name][0] / max(sums[name][1], 1e-300)))
                sums[name][:2] = 0.0
    overall = {name: math.sqrt(s[2] / max(s[3], 1e-300)) for name, s in sums.items()}
    return {'t': t, 'windows': windows, 'rel_l2': overall,
            'coordinates': runs['derivatives'].coordinates,
            'seconds_per_step': _step_costs(scene, band, dt)}


def _step_costs(swing, band: FilterBand, dt: float, steps: int = 2000) -> dict:
    """
    Median time per step of the derivatives band, turning and translating.

    Median time per step of the derivatives band on the turning clamp and on the translating
    sheet_10x10 (the same sheet and band), s.
    """
    costs = {}
    for scene in (swing, load_scene('sheet_10x10')):
        model = MassSpringModel(scene)
        sim = ModalSimulation(model, ModalBasis(model), band,
                              ModalSettings(dt=dt, basis_kind='derivatives'))
        sim.step(200)
        samples = []
        for _ in range(5):
            start = time.perf_counter()
            sim.step(steps // 5)
            samples.append((time.perf_counter() - start) / (steps // 5))
        costs[scene.name] = float(np.median(samples))
    return costs
