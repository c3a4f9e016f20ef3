"""
An integrator is one module and one registry entry: it owns its stability limit.

A toy integrator from the test folder (``toy_integrators.SymplecticEuler``, which states its
limit as ``1 / omega``) is registered by name alone; a run with it steps a single oscillator
at its analytic frequency, and every stability check asks its limit: a step between
``1 / omega`` and ``2 / omega`` (stable for the explicit Newmark step) is refused for it.
"""
from __future__ import annotations

import math

from helpers import oscillator
from modal_spring_ros.core import integrators
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.simulations.step_limits import UnstableStepError
import numpy as np
import pytest
from toy_integrators import SymplecticEuler


@pytest.fixture
def registered(monkeypatch):
    monkeypatch.setitem(integrators.INTEGRATORS, SymplecticEuler.name, SymplecticEuler)
    return SymplecticEuler.name


@pytest.mark.parametrize('method', ['full', 'modal'])
def test_a_toy_integrator_is_asked_its_own_stability_limit(registered, method):
    scene = oscillator(k=400.0, m=0.25)                  # omega = 40 rad/s
    omega = math.sqrt(400.0 / 0.25)
    assert integrators.stable_step(registered, omega) == pytest.approx(1.0 / omega)
    between = 1.5 / omega                                # stable for explicit, not for it
    build_simulation(scene, SimulationConfig(method=method, dt=between))
    with pytest.raises(UnstableStepError, match=f'{registered} stability limit 0.025 s'):
        build_simulation(scene, SimulationConfig(method=method, integrator=registered,
                                                 dt=between))


def test_a_toy_integrator_steps_the_oscillator_at_its_frequency(registered):
    scene = oscillator(k=400.0, m=0.25)
    sim = build_simulation(scene, SimulationConfig(method='full', integrator=registered,
                                                   dt=1e-4))
    n = sim.model.n_free_dof
    sim.set_state(np.full(n, 0.01), np.zeros(n))
    quarter = int(round(0.25 * 2.0 * math.pi / 40.0 / 1e-4))
    sim.step(2 * quarter)                                # half a period: -0.01
    assert sim.displacement()[0] == pytest.approx(-0.01, rel=1e-2)
