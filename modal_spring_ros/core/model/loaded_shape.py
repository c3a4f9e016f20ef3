"""
The loaded shape: the static equilibrium a scene hangs in, and whether its modes need it.

A cloth modelled flat in 3D, or a cable, has no stiffness across itself at rest: its rest
stiffness is singular (each particle can move out of the cloth's plane, each joint of the cable
can hinge, at no cost), so rest modes call it a mechanism. Hanging under gravity it does have
that stiffness, from the tension of its springs: about the shape it hangs in, the tangent
stiffness (material plus geometric, :func:`~.stiffness.assemble_stiffness`) is definite, and its
modes are the cloth's swaying and the cable's swinging. :func:`settle` finds that shape, with the
fixed particles where the clamp holds them at rest, and returns the scene about it.

The solve minimises the potential energy (springs plus gravity) over the free particles by a
projected Newton method: the compressed springs' negative geometric term is left out of the
Hessian so that every step is a descent direction, and a Levenberg term ``mu M`` bridges the
directions with no stiffness yet (the flat start); a backtracking line search on the energy keeps
each step downhill, and a small, seeded out-of-plane nudge at the start lets the descent leave a
flat saddle (a cloth hanging from its corners wrinkles). It ends where the force on every free
particle is below :data:`FORCE_RTOL` of its weight (or the descent has stalled at the round-off of
the forces, below :data:`STALLED_RTOL` of it) and the tangent has no negative mode: an
equilibrium that would buckle is left along its buckling mode, and the descent goes on.
"""
from __future__ import annotations

import dataclasses
import time
from typing import Callable

from modal_spring_ros.core.model.definite_factor import (elimination_order, factor_definite,
                                                         negative_pivots)
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.model.scene import Scene, SceneError
from modal_spring_ros.core.model.stiffness import assemble_stiffness, reduce_to_free
import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as spla

#: the equilibrium is found when no free particle's residual force exceeds this share of the
#: largest weight
FORCE_RTOL = 1e-8
#: most Newton steps before the search is given up
MAX_ITERATIONS = 400
#: a first step longer than this (s) is announced, with how many steps shapes usually take
SLOW_STEP_S = 2.0
#: how many steps most loaded shapes take (cloth meshes of 400-10,000 vertices: 9-30)
TYPICAL_STEPS = '10-30'
#: a search whose largest force has not fallen by a tenth in this many steps in a row has reached
#: the round-off of its forces: found, if the force left is below STALLED_RTOL of the largest
#: weight (a fine mesh's many small weights hang from springs whose forces are far larger)
STALLED_STEPS = 3
STALLED_RTOL = 1e-5
#: the start is nudged across the object by this share of its size (seeded: reproducible)
NUDGE = 1e-5
#: equilibria left along a buckling mode before the last one found is taken
MAX_ESCAPES = 8
#: how far along it, as a share of the object's size
ESCAPE = 1e-3
#: a tangent eigenvalue below minus this share of the mean diagonal is a buckling mode
UNSTABLE_RTOL = 1e-9
#: a tangent this size or smaller is checked with dense eigh
DENSE_LIMIT = 1500
#: a shape spans fewer directions than the scene has when its next singular value is below this
#: share of its largest
FLAT_RTOL = 1e-9


def needs_loaded_shape(scene: Scene) -> bool:
    """
    Tell whether the rest stiffness is singular for want of tension, and gravity gives it.

    Two signs, either enough: the shape spans fewer directions than the scene moves in (a flat
    cloth in 3D, a straight cable in a plane), or it has fewer springs than free coordinates (a
    chain, however bent, hinges). Without gravity there is no loaded shape to take.
    """
    if not np.any(scene.gravity[list(scene.axes)]):
        return False
    return (scene.n_springs < scene.n_free_dof
            or spanned_directions(scene.rest_positions[:, list(scene.axes)]) < scene.dimension)


def spanned_directions(points: np.ndarray) -> int:
    """Return how many directions the points span (1: on a line, 2: in a plane)."""
    centred = points - points.mean(axis=0)
    values = np.linalg.svd(centred, compute_uv=False)
    if values.size == 0 or values[0] == 0.0:
        return 0
    return int(np.sum(values > FLAT_RTOL * values[0]))


def settle(scene: Scene, progress: Callable[[str], None] | None = None) -> Scene:
    """
    Return ``scene`` about its static equilibrium under gravity (the shape it hangs in).

    Its ``rest_positions`` become the loaded shape, ``unloaded_positions`` keep the shape as
    built; rest lengths, masses and everything else stay. ``progress`` hears how long a step
    takes when it takes long (a scene of a million particles), and every tenth step.

    :raises SceneError: no gravity to hang from, no equilibrium found, or not memory enough
        for the factor of its tangent.
    """
    if scene.loaded:
        return scene
    if not np.any(scene.gravity):
        raise SceneError(f"scene '{scene.name}': a loaded shape needs gravity to hang from")
    try:
        return _settled(scene, progress)
    except MemoryError:
        coordinates = int(np.count_nonzero(~np.asarray(scene.fixed))) * len(scene.axes)
        raise SceneError(
            f"scene '{scene.name}': finding the shape it hangs in (a sparse factor of "
            f'{coordinates:,} coordinates) needs more memory than the sparse solver could have: '
            "a coarser mesh does, or 'reference: rest' (modes about the shape as built)") from None


def _settled(scene: Scene, progress: Callable[[str], None] | None) -> Scene:
    shape = _Energy(MassSpringModel(scene))
    axes, free_dof, mass, weight = shape.model.axes, shape.free_dof, shape.mass, shape.weight
    x = shape.model.rest.copy()
    size = max(float(np.max(np.ptp(x, axis=0))), 1e-12)
    x.reshape(-1)[free_dof] += NUDGE * size * np.random.default_rng(0).standard_normal(
        free_dof.size)
    tolerance = FORCE_RTOL * float(np.max(np.abs(weight)))
    energy, force = shape.evaluate(x)
    mass_term = sp.diags(mass)
    mu = mu_floor = 0.0
    order = None  # the factors' elimination order: one for every step (one pattern)
    exact = False  # the full tangent, once the convex one makes full steps
    escapes = stalled = 0
    began = time.perf_counter()
    if progress is not None:
        progress(f'loaded shape: searching ({free_dof.size:,} free coordinates)')
    for iteration in range(1, MAX_ITERATIONS + 1):
        residual = float(np.max(np.abs(force)))
        if residual <= tolerance or (stalled >= STALLED_STEPS
                                     and residual <= STALLED_RTOL / FORCE_RTOL * tolerance):
            # Newton's steps stop at any equilibrium: one that buckles (a compressed cloth
            # with a softer shape beside it) is left along its buckling mode
            direction = _unstable_direction(shape.hessian(x, compression=True), mass_term, order)
            if direction is None or escapes == MAX_ESCAPES:
                break
            escapes += 1
            x.reshape(-1)[free_dof] += ESCAPE * size * direction
            energy, force = shape.evaluate(x)
            exact = False
            stalled = 0
            continue
        hessian = shape.hessian(x, compression=exact)
        if not mu:
            scale = float(np.mean(hessian.diagonal() / mass))
            mu, mu_floor = 1e-3 * scale, 1e-12 * scale
            order = elimination_order(hessian, shape.model.free_points)
        try:   # definite, unless the exact tangent is not
            step = factor_definite(hessian + mu * mass_term, definite=not exact,
                                   order=order).solve(force)
        except RuntimeError:  # a singular exact tangent: the convex one
            if not exact:
                raise
            exact = False
            continue
        if exact and not float(np.dot(force, step)) > 0.0:  # not downhill: the convex one
            exact = False
            continue
        x, energy, force, taken = shape.line_search(x, energy, force, step)
        stalled = stalled + 1 if float(np.max(np.abs(force))) > 0.9 * residual else 0
        mu = max(mu * (0.3 if taken == 1.0 else 10.0), mu_floor)
        exact = taken == 1.0
        if progress is not None and iteration == 1 and time.perf_counter() - began > SLOW_STEP_S:
            progress(f'loaded shape: a step of {free_dof.size:,} coordinates takes '
                     f'{time.perf_counter() - began:.0f} s; most shapes are found in '
                     f'{TYPICAL_STEPS} steps (at most {MAX_ITERATIONS})')
        if progress is not None and iteration % 10 == 0:
            progress(f'loaded shape: step {iteration}, largest force '
                     f'{residual / tolerance * FORCE_RTOL:.2e} of the largest weight')
    else:
        raise SceneError(
            f"scene '{scene.name}': no static equilibrium under gravity found in "
            f'{MAX_ITERATIONS} steps (a force of {residual:.3g} N is left): is the object held?')
    loaded = np.array(scene.rest_positions, dtype=float)
    loaded[:, axes] = x
    loaded.setflags(write=False)
    if progress is not None:
        moved = float(np.max(np.linalg.norm(loaded - scene.rest_positions, axis=1)))
        progress(f'loaded shape found in {iteration} steps: it hangs up to {moved:.4g} m '
                 'from its shape as built')
    return dataclasses.replace(scene, rest_positions=loaded,
                               unloaded_positions=scene.rest_positions)


def _unstable_direction(tangent: sp.csr_matrix, mass: sp.dia_matrix,
                        order: np.ndarray | None = None) -> np.ndarray | None:
    """
    Return the tangent's most negative mode (largest entry 1), or None when it has none.

    A large tangent is first factored (in ``order``): its negative pivots are its negative
    eigenvalues, so a definite one needs no eigenvalue (30 s for a 10,000-vertex cloth's, against
    1 s for the factor), and an indefinite one's are sought just below zero, where buckling
    modes are, a few more than it has.
    """
    scale = float(np.mean(tangent.diagonal() / mass.diagonal()))
    if tangent.shape[0] <= DENSE_LIMIT:
        values, vectors = scipy.linalg.eigh(tangent.toarray(), mass.toarray(),
                                            subset_by_index=(0, 0))
    else:
        negatives = negative_pivots(tangent, order=order)
        if not negatives:
            return None
        values = vectors = None
        for sigma in (-1e-6 * scale, -1e-3 * scale):  # near zero; then wider
            shifted = factor_definite(tangent - sigma * mass, definite=False, order=order)
            found, shapes = spla.eigsh(
                tangent.tocsc(), k=min(negatives + 4, tangent.shape[0] - 1), M=mass.tocsc(),
                sigma=sigma, which='LM', OPinv=spla.LinearOperator(
                    tangent.shape, matvec=shifted.solve, dtype=float))
            lowest = int(np.argmin(found))
            values, vectors = found[lowest:lowest + 1], shapes[:, lowest:lowest + 1]
            if values[0] < -UNSTABLE_RTOL * scale:
                break
    if values[0] >= -UNSTABLE_RTOL * scale:
        return None
    return vectors[:, 0] / np.max(np.abs(vectors[:, 0]))


class _Energy:
    """Potential energy of a scene's springs, bending and weight, its force, its convex Hessian."""

    def __init__(self, model: MassSpringModel):
        self.model = model
        self.scene = model.scene
        self.free_dof, self.mass, self.weight = model.free_dof, model.mass_dof, model.gravity_force
        #: an energy scale: the work of the weight over the object's size
        self.scale = float(np.sum(np.abs(self.weight))) * max(
            float(np.max(np.ptp(self.scene.rest_positions, axis=0))), 1e-12)

    def evaluate(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        """Energy, and the force on the free DOF (minus its gradient), at positions ``x``."""
        u = x.reshape(-1)[self.free_dof] - self.model.rest.reshape(-1)[self.free_dof]
        force = self.model.physical_forces.elastic_forces(u) + self.weight
        energy = self.model.energy(x, np.zeros(u.size))
        return energy['spring'] + energy['gravity'], force

    def hessian(self, x: np.ndarray, compression: bool) -> sp.csr_matrix:
        """
        Return the energy's Hessian on the free DOF (the tangent stiffness).

        Without compressed springs' geometric term unless ``compression``: then it may be
        indefinite.
        """
        full = assemble_stiffness(x, self.scene.springs, self.model.law, x.shape[1],
                                  stretched=True, compression=compression)
        hessian = reduce_to_free(full, self.free_dof)
        if self.model.bending_free is not None:  # constant: the bending is quadratic
            hessian = (hessian + self.model.bending_free).tocsr()
        return hessian

    def line_search(self, x: np.ndarray, energy: float, force: np.ndarray, step: np.ndarray
                    ) -> tuple[np.ndarray, float, np.ndarray, float]:
        """Return the first of full, half, quarter ... steps that lowers the energy enough."""
        slope = float(np.dot(force, step))  # the energy's decrease rate along the step
        taken = 1.0
        for _ in range(40):
            trial = x.copy()
            trial.reshape(-1)[self.free_dof] += taken * step
            trial_energy, trial_force = self.evaluate(trial)
            # near the end the energy changes by less than its round-off: there the force
            # falling is the measure
            if trial_energy <= energy - 1e-4 * taken * slope or (
                    abs(trial_energy - energy) <= 1e-11 * (abs(energy) + self.scale)
                    and np.max(np.abs(trial_force)) < np.max(np.abs(force))):
                return trial, trial_energy, trial_force, taken
            taken *= 0.5
        return x, energy, force, 0.0
