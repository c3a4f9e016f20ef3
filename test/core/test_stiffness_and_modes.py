"""Stiffness at rest (paper eqs. 3-13) and the modes (eq. 2), against closed forms."""
from __future__ import annotations

import math

from modal_spring_ros.core.basis import ModalBasis
from modal_spring_ros.core.model import MassSpringModel
from modal_spring_ros.core.stiffness import (assemble_stiffness, element_stiffness,
                                             local_stiffness_2d, rotation_matrix_2d)
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest


def test_chain_2_reduced_stiffness_is_the_papers_matrix():
    scene = load_scene('chain_2')
    k1, k2 = scene.stiffness
    model = MassSpringModel(scene)
    assert np.array_equal(model.stiffness_free.toarray(), [[k1 + k2, -k2], [-k2, k2]])


def test_chain_2_frequencies_match_the_closed_form():
    scene = load_scene('chain_2')
    k1, k2 = scene.stiffness
    m1, m2 = scene.mass[1], scene.mass[2]
    # det(K - w^2 M) = 0:  m1 m2 w^4 - (m1 k2 + m2 (k1 + k2)) w^2 + k1 k2 = 0
    b = m1 * k2 + m2 * (k1 + k2)
    disc = math.sqrt(b * b - 4 * m1 * m2 * k1 * k2)
    expected = np.sqrt([(b - disc) / (2 * m1 * m2), (b + disc) / (2 * m1 * m2)])
    basis = ModalBasis(MassSpringModel(scene))
    np.testing.assert_allclose(basis.omega, expected, rtol=1e-10)
    # mass-normalised: Phi^T M Phi = I
    phi = basis.vectors
    np.testing.assert_allclose(phi.T @ np.diag([m1, m2]) @ phi, np.eye(2), atol=1e-12)


@pytest.mark.parametrize('theta', [0.0, 0.3, math.pi / 4, 2.0, -1.1])
def test_element_matrix_is_T_transpose_Kbar_T(theta):
    k = 37.5
    expected = rotation_matrix_2d(theta).T @ local_stiffness_2d(k) @ rotation_matrix_2d(theta)
    got = element_stiffness(k, [math.cos(theta), math.sin(theta)])
    np.testing.assert_allclose(got, expected, atol=1e-12)
    # and the sparse assembly of that one spring gives the same matrix
    pos = np.array([[0.0, 0.0], [math.cos(theta), math.sin(theta)]]) * 0.7
    assembled = assemble_stiffness(pos, np.array([[0, 1]]), np.array([k]), 2).toarray()
    np.testing.assert_allclose(assembled, expected, atol=1e-12)


def test_rest_stiffness_is_the_force_jacobian_at_rest():
    """-df/du at the rest shape equals K (checks eq. 20 against eqs. 6-13)."""
    scene = load_scene('sheet_10x10')
    model = MassSpringModel(scene)
    n = model.n_free_dof
    f0 = model.free_force(np.zeros(n), 0.0)
    rng = np.random.default_rng(0)
    h = 1e-7
    k = model.stiffness_free
    for _ in range(5):
        d = rng.normal(size=n)
        jd = (model.free_force(h * d, 0.0) - model.free_force(-h * d, 0.0)) / (2 * h)
        np.testing.assert_allclose(-jd, k @ d, rtol=1e-6, atol=1e-6 * np.abs(k @ d).max())
    assert np.allclose(f0, model.gravity_force)  # springs at rest carry no force


def test_sparse_modes_agree_with_dense_modes():
    model = MassSpringModel(load_scene('sheet_10x10'))
    dense = ModalBasis(model)
    sparse = ModalBasis(model, dense_limit=0, initial_modes=20)
    assert not sparse.dense and sparse.count == 20
    np.testing.assert_allclose(sparse.omega, dense.omega[:20], rtol=1e-9)
    m = model.mass_dof
    np.testing.assert_allclose(sparse.vectors.T @ (m[:, None] * sparse.vectors), np.eye(20),
                               atol=1e-9)
    # more modes on demand keep the earlier ones
    sparse.ensure_count(45)
    assert sparse.count >= 45
    np.testing.assert_allclose(sparse.omega[:45], dense.omega[:45], rtol=1e-9)


def test_large_scene_never_goes_dense_and_gets_only_the_modes_asked_for():
    model = MassSpringModel(load_scene('sheet_100x100'))
    basis = ModalBasis(model, initial_modes=8)
    assert not basis.dense and basis.count == 8
    assert basis.vectors.shape == (19800, 8)
    assert basis.frequencies_hz[0] == pytest.approx(4.59, rel=0.01)
