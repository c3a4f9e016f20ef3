"""
Refuse an explicit step that a band's modes cannot take, before computing the band's modes.

A wide band on a large scene can need minutes of modes; if one of them is already unstable at
the step asked for, the band is refused having computed modes only up to the stability limit
``f = 1 / (pi dt)`` (``dt = 2 / omega``), never the rest. Both a band change on a running
modal simulation and a new modal simulation with a given step go through
:func:`check_step_before_modes`.
"""
from __future__ import annotations

import math

from modal_spring_ros.core.bases.basis import DEFAULT_MAX_MODES, ModalBasis
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.integrators import conditionally_stable, stable_step
from modal_spring_ros.core.simulations.step_limits import check_step


def mode_cap(basis: ModalBasis, max_modes: int | None) -> int:
    """Return the most rest modes a modal run computes (``max_modes``, or its default)."""
    return int(max_modes) if max_modes else (basis.n_dof if basis.dense else DEFAULT_MAX_MODES)


def check_step_before_modes(basis: ModalBasis, band: FilterBand, *, dt: float, integrator: str,
                            highest_hz: float | None, max_modes: int, method: str = 'modal',
                            dt_name: str = 'dt') -> None:
    """
    Refuse ``band`` when it keeps a rest mode unstable at ``dt``, computing modes only up to it.

    Modes above ``highest_hz`` (when given) and past ``max_modes`` are never stepped, so they
    are not checked. An unconditionally stable integrator, or a band whose top lies below the
    limit, costs nothing.

    :raises UnstableStepError: the band keeps a mode at or above the limit.
    """
    # the frequency whose limit is dt (the integrator's limit goes as 1 / omega)
    limit_hz = stable_step(integrator, 1.0) / dt / (2.0 * math.pi)
    top = min(band.top if band.by == 'hz' and band.bounded_above else math.inf,
              math.inf if highest_hz is None else highest_hz)
    if not conditionally_stable(integrator) or top < limit_hz:
        return
    count = int(band.top) + 1 if band.by == 'index' and band.bounded_above else math.inf
    basis.ensure_frequency(limit_hz, min(count, max_modes, basis.n_dof))
    f = basis.frequencies_hz
    over = band.keeps(f) & (f >= limit_hz) & (f <= top * (1.0 + 1e-12))
    over[max_modes:] = False
    if over.any():
        check_step(integrator, dt, 2 * math.pi * f[over].max(), method,
                   dt_name)
