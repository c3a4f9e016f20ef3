"""A large scene's modes kept between runs: read back instead of solved, and checked as input."""
from __future__ import annotations

import dataclasses

from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.bases.stored_modes import KEY_PREFIX, modes_key
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest


class DictStore:
    """A :class:`~modal_spring_ros.core.forces.base.SampleStore` in memory."""

    def __init__(self):
        self.entries = {}

    def load(self, key):
        entry = self.entries.get(key)
        return None if entry is None else dict(entry)

    def save(self, key, arrays):
        self.entries[key] = {name: np.array(value) for name, value in arrays.items()}

    def discard(self, key):
        self.entries.pop(key, None)

    def where(self, key):
        return f'memory:{key}'


@pytest.fixture
def model():
    return MassSpringModel(load_scene('sheet_32x32'))       # 1,984 free DOF: solved sparse


def test_the_next_run_reads_the_modes_back_instead_of_solving(model):
    store = DictStore()
    first = ModalBasis(model, samples=store)
    assert first.modes_solved == 32 and list(store.entries) == [modes_key(model)]
    said = []
    again = ModalBasis(MassSpringModel(model.scene), samples=store, progress=said.append)
    assert again.modes_solved == 0 and again._solver is None     # nothing solved or factored
    np.testing.assert_array_equal(again.omega, first.omega)
    np.testing.assert_array_equal(again.vectors, first.vectors)
    assert said == ['32 modes read from the cache: 4.621 .. 65.8 Hz']
    # more modes are solved for on top of them, and kept for the run after
    again.ensure_count(48)
    assert again.count >= 48 and store.entries[modes_key(model)]['omega'].size == again.count
    third = ModalBasis(MassSpringModel(model.scene), samples=store)
    np.testing.assert_array_equal(third.vectors, again.vectors)


def test_another_scene_has_another_key():
    scene = load_scene('sheet_32x32')
    stiffer = dataclasses.replace(scene, stiffness=np.asarray(scene.stiffness) * 1.01)
    keys = {modes_key(MassSpringModel(s)) for s in (scene, stiffer)}
    assert len(keys) == 2 and all(k.startswith(KEY_PREFIX) for k in keys)


@pytest.mark.parametrize('spoil, why', [
    (lambda e: e.update(vectors=e['vectors'] + 1e-3 * np.roll(e['vectors'], 1, axis=1)),
     'not mass-orthonormal'),
    (lambda e: e.update(omega=e['omega'] * 1.001), 'not modes of this scene (relative residual'),
    (lambda e: e.update(vectors=e['vectors'][:-2]), 'are not the modes of 1984 free DOF'),
    (lambda e: e['omega'].__setitem__(3, np.nan), 'non-finite values'),
    (lambda e: e.update(omega=e['omega'][::-1].copy(), vectors=e['vectors'][:, ::-1].copy()),
     'not positive and ascending'),
    (lambda e: e.pop('vectors'), 'not a modes entry')])
def test_a_spoilt_entry_is_refused_removed_and_the_modes_solved_again(model, spoil, why):
    store = DictStore()
    first = ModalBasis(model, samples=store)
    spoil(store.entries[modes_key(model)])
    said = []
    again = ModalBasis(MassSpringModel(model.scene), samples=store, progress=said.append)
    refusal = [line for line in said if 'refused' in line]
    assert len(refusal) == 1 and why in refusal[0], said
    assert refusal[0].startswith(f'modes cache entry memory:{modes_key(model)} refused: ')
    assert again.modes_solved == 32
    np.testing.assert_allclose(again.omega, first.omega, rtol=1e-10)
    # solved again, and kept again
    np.testing.assert_array_equal(store.entries[modes_key(model)]['omega'], again.omega)
