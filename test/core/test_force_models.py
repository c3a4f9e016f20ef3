"""The force model contract: registry, typed options and reports, a model added from outside."""
from __future__ import annotations

import math

from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation, force_options
from modal_spring_ros.core.forces import (force_model, ForceOptions, ForceReport, FORCES,
                                          RefreshedForces)
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest
from toy_forces import LinearForces


def test_options_name_a_registered_model_or_are_refused():
    assert force_model(ForceOptions('refreshed', 8)) is RefreshedForces
    with pytest.raises(ValueError, match="force model 'magic' must be one of exact, refreshed"):
        force_model(ForceOptions('magic'))
    with pytest.raises(ValueError, match=r'force refresh \(0\) must be a whole number'):
        force_model(ForceOptions('refreshed', 0))
    with pytest.raises(ValueError, match=r'force tolerance \(nan\) must be above 0'):
        force_model(ForceOptions('exact', tolerance=math.nan))


def test_the_run_settings_map_onto_a_model():
    """``modal.force_refresh`` alone asks for refreshed forces; every step is exact."""
    assert force_options('exact', 10, 0.01) == ForceOptions('refreshed', 10, 0.01)
    assert force_options('exact', 1, 0.01) == ForceOptions('exact', 1, 0.01)
    assert force_options('sampled', 1, 0.01) == ForceOptions('sampled', 1, 0.01)


def test_a_model_from_outside_the_package_runs_through_the_registry_alone(monkeypatch):
    """
    One registry entry makes a new model a run's choice everywhere (config, factory, report).

    The linearised springs sag under gravity by ``g / omega^2`` per coordinate: the run settles
    there, near the nonlinear run (small deformation), but not on it.
    """
    monkeypatch.setitem(FORCES, LinearForces.name, LinearForces)
    scene = load_scene('sheet_10x10')
    config = SimulationConfig(forces='linear', basis='rest', dt=5e-4)
    linear = build_simulation(scene, config)
    exact = build_simulation(scene, SimulationConfig(basis='rest', dt=5e-4))
    assert isinstance(linear._forces, LinearForces)
    linear.step(2000)
    exact.step(2000)
    report = linear.status().forces
    assert report == ForceReport('linear', 'linear springs (2001 calls)', 0)
    assert linear.evaluated_share == 0.0
    sag = linear.displacement()
    reference = exact.displacement()
    difference = np.linalg.norm(sag - reference) / np.linalg.norm(reference)
    assert 1e-6 < difference < 0.05, difference
    monkeypatch.delitem(FORCES, LinearForces.name)
    with pytest.raises(ValueError, match="forces 'linear' must be one of exact, refreshed"):
        build_simulation(scene, config)
