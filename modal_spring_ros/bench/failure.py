"""Where the paper's method fails, and what holds there: the large-deformation scene
(``sheet_10x10_resonance``), rest modes and their derivatives against the full run."""
from __future__ import annotations

import math

from modal_spring_ros.core.basis import ModalBasis
from modal_spring_ros.core.config import DEFAULT_STRAIN_WARNING
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.model import MassSpringModel
from modal_spring_ros.core.simulations import DivergenceError, FullSimulation, ModalSimulation
from modal_spring_ros.scenes.resources import load_scene


def failure(progress, duration: float) -> dict:
    """The large-deformation scene: 15-mode low-pass (paper fig. 10b) against the full run,
    with rest modes and with their derivatives: windowed relative error over time, and the
    strain the node watches."""
    progress("failure: sheet_10x10_resonance, 15 modes against full")
    model = MassSpringModel(load_scene("sheet_10x10_resonance"))
    basis = ModalBasis(model)
    dt = model.scene.default_dt
    full = FullSimulation(model, dt=dt, basis=basis)
    band = FilterBand("lowpass", 0, 14, "index")
    modal = ModalSimulation(model, basis, band, dt=dt)
    derived = ModalSimulation(model, basis, band, dt=dt, basis_kind="derivatives")
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
    return {"t": t, "rel_l2_window": err, "modal_strain": strain, "full_strain": full_strain,
            "error_passes_10pct_at": crossing, "strain_warning_at": warn,
            "strain_warning": DEFAULT_STRAIN_WARNING, "modal_diverged_at": diverged_at,
            "derivatives_rel_l2_window": derived_err,
            "derivatives_rel_l2": math.sqrt(derived_all_num / max(all_den, 1e-300)),
            "derivatives_coordinates": derived.coordinates}
