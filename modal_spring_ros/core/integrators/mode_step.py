"""
What an integrator's step does to a vibration mode: the frequency and decay it gives it.

Read from the integrator itself (one step of every mode at once, the eigenvalues of that step's
map), so that an integrator added to the registry is judged without a formula of its own: the
period error and numerical damping of a step (:mod:`~modal_spring_ros.core.auto.step_error`
predicts a full run's step error from them).
"""
from __future__ import annotations

from modal_spring_ros.core.integrators import DiagonalOperators, integrator
import numpy as np


def scheme_frequencies(name: str, omega: np.ndarray, damping: np.ndarray, dt: float
                       ) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the frequency and decay rate (rad/s, 1/s) the integrator ``name`` gives each mode.

    A mode of circular frequency ``omega`` and damping coefficient ``damping`` (``q'' + c q' +
    omega^2 q = 0``), stepped by ``dt``: the complex eigenvalue ``z`` of one step's map is
    ``exp((-sigma + i w) dt)``. Beyond the integrator's stability limit the decay is negative.
    """
    omega = np.asarray(omega, dtype=float)
    n = omega.size
    stiffness = omega ** 2
    ops = DiagonalOperators(1.0, np.asarray(damping, dtype=float), stiffness, dt)
    scheme = integrator(name)

    def force(u: np.ndarray) -> np.ndarray:
        return -stiffness * u

    # the step's map on (u, v, a), column by column (the state a step starts from)
    columns = []
    for k in range(3):
        state = [np.zeros(n), np.zeros(n), np.zeros(n)]
        state[k] = np.ones(n)
        result = scheme.step(state[0], state[1], state[2], dt, force, ops)
        columns.append(np.stack([result.u, result.v, result.a], axis=-1))
    maps = np.stack(columns, axis=-1)                     # (n, 3, 3): row = output
    roots = np.linalg.eigvals(maps)                       # (n, 3)
    # the oscillation's pair: the roots of largest modulus, the one turning positively
    order = np.argsort(-np.abs(roots) + 1e-12 * -roots.imag, axis=1)
    root = np.take_along_axis(roots, order[:, :1], axis=1)[:, 0]
    root = np.where(root.imag < 0, root.conj(), root)
    with np.errstate(divide='ignore'):
        sigma = -np.log(np.abs(root)) / dt
    return np.abs(np.angle(root)) / dt, sigma
