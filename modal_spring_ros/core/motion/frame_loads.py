"""
The inertial loads of a turning clamp's frame (the floating frame of reference).

Written in the clamp's frame, ``x = R (X + u) + b``
(:mod:`~modal_spring_ros.core.motion.rigid_frame`), the deformation ``u`` stays small while the
body turns, and every particle of mass ``m`` feels

    m u'' = f_spring(X + u) + m R^T g - m R^T b'' - m A (X + u) - 2 m W u'

with ``W = R^T R'`` (the angular velocity, as a cross-product matrix, in the frame) and
``A = R^T R'' = [alpha]x + [omega]x^2``: gravity turned into the frame, the frame's
translation, the Euler and centrifugal loads, and the Coriolis load. Spring forces do not see
the frame (a rigid turn stretches no spring), so they stay the exact ones of eq. 20.

Every term is linear in ``X``, ``u`` or ``u'``, so its projection on the stepped coordinates
``u = Phi q`` is precomputed once per basis: per step it is a few products with ``d + d^2``
columns and one ``m x d^2 m`` matrix, nothing per particle or spring.
"""
from __future__ import annotations

import numpy as np


class FrameLoads:
    """
    Generalized inertial loads of the clamp's frame on coordinates ``phi`` (n_free_dof, m).

    :meth:`loads` is the part that does not depend on the state (gravity turned into the
    frame, the frame's translation, and the Euler and centrifugal loads of the rest shape);
    :meth:`coupling` the part linear in ``q`` and ``q'`` (Euler and centrifugal loads of the
    displacement, and the Coriolis load).
    """

    def __init__(self, model, phi: np.ndarray, coupling: bool = True):
        """``coupling``: whether :meth:`coupling` is wanted (its ``m x d^2 m`` matrix is made)."""
        d = model.dimension
        self.model = model
        mass = model.scene.mass[model.free_particles]                 # (p,)
        rows = [phi[a::d] for a in range(d)]                          # (p, m) per axis
        m = phi.shape[1]
        self._gravity = np.asarray(model.scene.gravity, dtype=float)[model.axes]
        # per axis i: the pattern M 1_i, then M (e_i X_j) for each j (frame_load_patterns)
        projected = (phi.T @ np.column_stack(frame_load_patterns(model))).reshape(m, d, d + 1)
        #: Phi^T M 1_i: a unit acceleration of every particle along axis i
        self._unit = np.ascontiguousarray(projected[:, :, 0])
        #: Phi^T M (e_i X_j): axis-i loads in proportion to the rest coordinate j (i-major)
        self._rest = np.ascontiguousarray(projected[:, :, 1:].reshape(m, d * d))
        #: Phi_i^T M Phi_j for every axis pair, laid out (m, d*d*m) for one product per step
        self._coupling = None
        if coupling:
            pairs = np.stack([rows[i].T @ (mass[:, None] * rows[j])
                              for i in range(d) for j in range(d)])   # (d*d, m, m)
            self._coupling = np.ascontiguousarray(pairs.transpose(1, 0, 2).reshape(m, -1))

    def loads(self, t: float) -> np.ndarray:
        """State-independent generalized load at ``t``."""
        frame = self.model.frame(t)
        turned = (self._gravity - frame.acceleration) @ frame.rotation     # R^T (g - b'')
        return self._unit @ turned - self._rest @ frame.angular_acceleration.ravel()

    def coupling(self, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """
        Generalized load of the displacement and velocity ``q``, ``v`` at ``t``.

        ``-Phi^T M (A Phi q + 2 W Phi v)``.
        """
        frame = self.model.frame(t)
        z = np.multiply.outer(frame.angular_acceleration.ravel(), q)
        z += np.multiply.outer(2.0 * frame.angular_velocity.ravel(), v)
        return -(self._coupling @ z.ravel())


def frame_load_patterns(model) -> list[np.ndarray]:
    """
    Return the load patterns of a turning clamp's frame (per free DOF).

    ``M 1_a`` (gravity and the frame's translation, turned) and ``M (e_i X_j)`` (the centrifugal
    and Euler loads of the rest shape), for every axis ``a``, ``i``, ``j``.
    """
    d = model.dimension
    mass = model.scene.mass[model.free_particles]
    rest = model.rest[model.free_particles]
    patterns = []
    for i in range(d):
        for weight in (np.ones(mass.size), *rest.T):
            load = np.zeros(model.n_free_dof)
            load[i::d] = mass * weight
            patterns.append(load)
    return patterns
