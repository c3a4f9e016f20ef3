"""Stiffness at rest (paper eqs. 3-13) and the modes (eq. 2), against closed forms."""
from __future__ import annotations

import math

from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.laws import LinearSpring
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.model.stiffness import (assemble_stiffness, element_stiffness,
                                                   local_stiffness_2d, rotation_matrix_2d)
from modal_spring_ros.scenes.resources import load_scene
from modal_spring_ros.scenes.sized import sized_scene
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
    assembled = assemble_stiffness(pos, np.array([[0, 1]]), LinearSpring([k], [0.7]), 2).toarray()
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


def test_modes_up_to_a_frequency_are_solved_for_only_as_far_as_affordable():
    """``ensure_frequency``'s ``affords``: asked before each solve with how many it solves for."""
    model = MassSpringModel(load_scene('sheet_32x32'))
    basis = ModalBasis(model, initial_modes=8)
    top = float(basis.frequencies_hz[-1])
    asked = []

    def refuses(solved: int) -> bool:
        asked.append(solved)
        return False
    assert not basis.ensure_frequency(3.0 * top, 200, refuses)
    assert basis.count == 8 and asked == [basis.to_solve(24)] == [24]
    # affordable: solved for until the highest mode passes the frequency, and no further
    assert basis.ensure_frequency(2.5 * top, 200, lambda solved: solved <= 64)
    assert basis.frequencies_hz[-1] > 2.5 * top and basis.count <= 64
    grown = basis.count
    # a solve beyond what is afforded stops it where it stands
    assert not basis.ensure_frequency(10.0 * top, 200, lambda solved: solved <= grown)
    assert basis.count == grown and basis.frequencies_hz[-1] <= 10.0 * top


@pytest.mark.parametrize('scene', [lambda: load_scene('sheet_32x32'),
                                   lambda: sized_scene('sheet', 64)],
                         ids=['sheet_32x32', 'sheet_64x64'])
def test_the_modes_reaching_a_frequency_are_estimated_from_how_their_count_grew(scene):
    """
    ``reaching``: the count of the lowest modes up to a frequency, from the 32 there are.

    On a sheet the count grows about as the square of the frequency: the estimate (a quarter
    more) covers the modes really up to twice the highest, without twice as many again, and
    ``ensure_frequency`` reaches there in one solve (doubling took two: 64, then 128).
    """
    model = MassSpringModel(scene())
    basis = ModalBasis(model, initial_modes=32)
    target = 2.0 * float(basis.frequencies_hz[-1])
    estimate = basis.reaching(target)
    richer = ModalBasis(model, initial_modes=min(2 * estimate, model.n_free_dof - 2))
    needed = int(np.searchsorted(richer.frequencies_hz, target, side='right')) + 1
    assert needed <= estimate <= 1.5 * needed
    solved = basis.modes_solved
    assert basis.ensure_frequency(target, 1000)
    assert basis.modes_solved == solved + estimate and basis.frequencies_hz[-1] > target
    assert ModalBasis(model, initial_modes=8).reaching(target) == 0     # too few to tell


def _tie_broken_the_other_way(lowest):
    """Wrap ``ShiftInvertModes.lowest``: a mode with a tied largest pair comes back negated."""
    def wrapped(self, count):
        lam, phi = lowest(self, count)
        phi = phi.copy()
        for j in range(phi.shape[1]):
            order = np.argsort(-np.abs(phi[:, j]))
            a, b = order[:2]
            if abs(abs(phi[a, j]) - abs(phi[b, j])) <= 1e-12 * abs(phi[a, j]):
                phi[:, j] *= -1.0                   # the solver's sign is arbitrary ...
                phi[b, j] *= 1.0 + 1e-13            # ... and round-off breaks the tie
        return lam, phi
    return wrapped


def test_modes_already_computed_stay_as_they_are_when_the_basis_grows(monkeypatch):
    """
    A mode with two largest components of equal size and opposite sign.

    (``sheet_32x32`` mode 14) must not come back with its sign flipped when the basis grows,
    whatever the eigensolver's round-off does with the tie: a run carries its state over by
    mode index.
    """
    from modal_spring_ros.core.bases.shift_invert import ShiftInvertModes
    model = MassSpringModel(load_scene('sheet_32x32'))
    basis = ModalBasis(model, initial_modes=16)
    before = basis.vectors.copy()
    tied = [j for j in range(16) if np.sum(np.isclose(np.abs(before[:, j]),
                                                      np.abs(before[:, j]).max(),
                                                      rtol=1e-12)) >= 2]
    assert tied, 'the scene has no mode with a tied largest component any more'
    monkeypatch.setattr(ShiftInvertModes, 'lowest', _tie_broken_the_other_way(
        ShiftInvertModes.lowest))
    basis.ensure_count(48)
    assert basis.count >= 48
    np.testing.assert_array_equal(basis.vectors[:, :16], before)
    m = model.mass_dof
    np.testing.assert_allclose(basis.vectors.T @ (m[:, None] * basis.vectors),
                               np.eye(basis.count), atol=1e-9)
    # the modes added are modes: K phi = omega^2 M phi
    k = model.stiffness_free
    phi = basis.vectors[:, 16:]
    residual = k @ phi - m[:, None] * phi * basis.omega[16:] ** 2
    assert np.linalg.norm(residual) <= 1e-6 * np.linalg.norm(k @ phi)


def test_a_degenerate_pair_cut_by_the_old_count_keeps_its_member_and_adds_its_partner():
    """The fresh modes rotate a degenerate pair; the kept member stays, its partner is added."""
    from modal_spring_ros.core.bases.basis import _grown
    rng = np.random.default_rng(3)
    mass = rng.uniform(0.5, 2.0, 8)
    lam = np.array([1.0, 2.0, 3.0, 3.0, 5.0, 6.0, 7.0, 8.0])
    # an M-orthonormal eigenbasis of diag(lam) in the M inner product
    q, _ = np.linalg.qr(rng.normal(size=(8, 8)))
    phi = q / np.sqrt(mass)[:, None]                      # phi^T M phi = I
    old = phi[:, :3]                                      # cut inside the pair (modes 2, 3)
    turn = np.array([[np.cos(0.7), -np.sin(0.7)], [np.sin(0.7), np.cos(0.7)]])
    fresh = phi[:, :6].copy()
    fresh[:, 2:4] = fresh[:, 2:4] @ turn                  # the solver picks another pair basis
    fresh[:, 0] *= -1.0                                   # and another sign
    new_lam, new_phi = _grown(lam[:3], old, lam[:6], fresh, mass)
    np.testing.assert_array_equal(new_phi[:, :3], old)
    np.testing.assert_allclose(new_lam, lam[:6])
    np.testing.assert_allclose(new_phi.T @ (mass[:, None] * new_phi), np.eye(6), atol=1e-12)
    # the added mode 3 is the partner of the kept member 2 within the pair
    np.testing.assert_allclose(np.abs(new_phi[:, 3] @ (mass * phi[:, 3])), 1.0, atol=1e-12)
