"""The nested dissection ordering of large factors: valid, lower in fill, the same solutions."""
from __future__ import annotations

from modal_spring_ros.core.bases.shift_invert import ShiftInvertModes
from modal_spring_ros.core.model.definite_factor import (DISSECTION_MIN_ROWS, factor_definite,
                                                         negative_pivots, OrderedFactor)
from modal_spring_ros.core.model.dissection import nested_dissection
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.scenes.sized import sized_scene
import numpy as np
import pytest
import scipy.sparse as sp


def _shifted(kind: str, side: int) -> tuple[MassSpringModel, sp.csc_matrix]:
    model = MassSpringModel(sized_scene(kind, side))
    return model, (model.stiffness_free + sp.diags(1e-3 * model.mass_dof)).tocsc()


def test_the_order_is_a_permutation_that_keeps_each_particles_rows_together():
    model, matrix = _shifted('block', 9)
    order = nested_dissection(matrix, model.free_points)
    assert np.array_equal(np.sort(order), np.arange(matrix.shape[0]))
    blocks = order.reshape(-1, 3)
    assert np.all(blocks % 3 == np.arange(3)) and np.all(np.diff(blocks // 3, axis=1) == 0)


def test_the_first_split_leaves_two_uncoupled_halves_and_a_thin_separator_last():
    """Eliminated in this order, the two halves never fill in between them."""
    side = 40
    model, matrix = _shifted('sheet', side)
    order = nested_dissection(matrix, model.free_points)
    coupled = sp.csr_matrix(matrix)[order][:, order]
    graph = (abs(coupled[::2, ::2]) + abs(coupled[1::2, 1::2])).tocsr()
    p = matrix.shape[0] // 2
    low, high = p // 2, p - p // 2    # the halves, the separator taken from the low one

    def uncoupled(separator: int) -> bool:
        first = low - separator
        return graph[:first, first:first + high].nnz == 0

    separator = next(s for s in range(low + 1) if uncoupled(s))
    # one lattice line of a 40 x 39 sheet (its top row fixed): a column of 39 particles
    assert separator == side - 1
    assert graph[p - separator:, :low - separator].nnz > 0      # it joins both halves
    assert graph[p - separator:, low - separator:p - separator].nnz > 0


@pytest.mark.parametrize('kind, side, most', [('sheet', 60, 0.95), ('block', 12, 0.7)])
def test_a_large_factor_fills_less_than_with_minimum_degree(kind, side, most):
    model, matrix = _shifted(kind, side)
    assert matrix.shape[0] >= DISSECTION_MIN_ROWS
    dissected = factor_definite(matrix, points=model.free_points)
    minimum_degree = factor_definite(matrix)
    assert isinstance(dissected, OrderedFactor)
    assert dissected.nnz < most * (minimum_degree.L.nnz + minimum_degree.U.nnz)


@pytest.mark.parametrize('definite', [True, False])
def test_an_ordered_factor_solves_vectors_and_columns_in_the_matrixs_own_order(definite):
    model, matrix = _shifted('block', 10)
    factor = factor_definite(matrix, definite=definite, points=model.free_points)
    rhs = np.random.default_rng(3).standard_normal((matrix.shape[0], 4))
    for b in (rhs[:, 0], rhs):
        x = factor.solve(b)
        assert x.shape == b.shape
        assert np.linalg.norm(matrix @ x - b) < 1e-10 * np.linalg.norm(b)


def test_modes_are_the_same_whichever_order_factors_them():
    model = MassSpringModel(sized_scene('sheet', 45))
    plain = ShiftInvertModes(model.stiffness_free, model.mass_dof)
    dissected = ShiftInvertModes(model.stiffness_free, model.mass_dof, model.free_points)
    assert isinstance(dissected._factorised(), OrderedFactor)
    lam_plain, phi_plain = plain.lowest(8)
    lam, phi = dissected.lowest(8)
    np.testing.assert_allclose(lam, lam_plain, rtol=1e-10)
    overlap = np.abs(np.einsum('ij,i,ij->j', phi, model.mass_dof, phi_plain))
    np.testing.assert_allclose(overlap, 1.0, atol=1e-8)


def test_rows_that_are_not_blocks_of_the_particles_are_refused():
    model, matrix = _shifted('sheet', 10)
    with pytest.raises(ValueError, match='not blocks'):
        nested_dissection(matrix, model.free_points[:-1])


@pytest.mark.parametrize('ordered', [False, True])
def test_negative_pivots_count_the_negative_eigenvalues(ordered):
    """Sylvester's law of inertia: a stiffness shifted past its lowest modes has that many."""
    model, _ = _shifted('sheet', 48)
    k = model.stiffness_free.tocsc()
    mass = sp.diags(model.mass_dof)
    order = nested_dissection(k, model.free_points) if ordered else None
    omega2 = ShiftInvertModes(k, model.mass_dof).lowest(6)[0]
    assert negative_pivots(k, order=order) == 0
    for below in (1, 3, 5):   # shifted between modes below and below + 1
        shift = 0.5 * (omega2[below - 1] + omega2[below])
        assert negative_pivots((k - shift * mass).tocsc(), order=order) == below
    singular = (k - omega2[0] * mass).tolil()
    singular[0, :] = 0.0
    singular[:, 0] = 0.0
    assert negative_pivots(singular.tocsc(), order=order) >= 1
