"""
A scene's colliders as Newton shapes, and Newton's particle-shape contact set as the project's.

Planes, spheres and boxes fixed in the world become static Newton shapes (``body = -1``). The
particles' soft contact takes what the project's explicit contact takes at the same step
(:mod:`~modal_spring_ros.core.loads.contact`): the stiffness ``k = m (c / dt)^2`` at the
contact's most ``c``, critical normal damping, and the scene's sliding friction as Newton's
Coulomb coefficient (Newton has one; its sliding is regularised by a viscous ``kf``, here
stopping a particle's slip within about two steps). Each step runs Newton's collision pipeline
before its solver, as Newton's examples do; the particles are points (radius 0), detected
within :data:`GAP` of a shape.
"""
from __future__ import annotations

import math

from modal_spring_ros.core.loads.contact import CONTACT_RATE, DAMPING_RATIO
from modal_spring_ros.core.model.scene import Scene
import numpy as np

try:
    import newton
    import warp as wp
except ImportError:     # the optional 'peer' extra (newton_peer says so)
    newton = wp = None

#: the collider shapes the peer places
SUPPORTED = ('plane', 'sphere', 'box')
#: how near a shape a particle is a contact candidate, m
GAP = 0.01
#: the friction's viscous regularisation: this share of ``m / dt`` per m/s of slip
SLIP_SHARE = 0.5


def contact_refusal(scene: Scene) -> str:
    """Return why the peer cannot place ``scene``'s colliders as the project does, or ''."""
    contact = scene.contact
    if contact is None:
        return ''
    if contact.attached:
        return "colliders attached to frames (the peer's are fixed in the world)"
    other = sorted({c.shape for c in contact.colliders} - set(SUPPORTED))
    if other:
        return f"{', '.join(other)} colliders (the peer places {', '.join(SUPPORTED)})"
    return ''


class NewtonContact:
    """The colliders of ``scene`` added to a Newton ``builder``; :meth:`collide` each step."""

    def __init__(self, builder, scene: Scene, dt: float):
        mass = float(np.max(scene.mass[~scene.fixed]))
        self.ke = mass * (CONTACT_RATE[1] / dt) ** 2
        self.kd = 2.0 * DAMPING_RATIO * math.sqrt(self.ke * mass)
        self.kf = SLIP_SHARE * mass / dt
        self.mu = float(scene.contact.sliding_friction)
        cfg = newton.ModelBuilder.ShapeConfig(ke=self.ke, kd=self.kd, kf=self.kf, mu=self.mu)
        for collider in scene.contact.colliders:
            _add_shape(builder, collider, cfg)
        self._pipeline = self._contacts = None

    def finalize(self, model) -> None:
        """Give the finalised ``model`` the particles' side of the contact and the pipeline."""
        model.soft_contact_ke, model.soft_contact_kd = self.ke, self.kd
        model.soft_contact_kf, model.soft_contact_mu = self.kf, self.mu
        self._pipeline = newton.CollisionPipeline(model, broad_phase='nxn', soft_contact_gap=GAP)
        self._contacts = self._pipeline.contacts()

    def collide(self, state):
        """Return the contacts of ``state``'s particles with the shapes."""
        self._pipeline.collide(state, self._contacts)
        return self._contacts


def _add_shape(builder, collider, cfg) -> None:
    if collider.shape == 'plane':
        n = np.asarray(collider.normal, dtype=float)
        builder.add_shape_plane(plane=(*n.tolist(), -float(n @ collider.point)), width=0.0,
                                length=0.0, body=-1, cfg=cfg)
        return
    where = wp.transform(wp.vec3(*np.asarray(collider.center, dtype=float).tolist()),
                         wp.quat_identity())
    if collider.shape == 'sphere':
        builder.add_shape_sphere(-1, xform=where, radius=float(collider.radius), cfg=cfg)
    else:
        hx, hy, hz = (float(h) for h in collider.half_extents)
        builder.add_shape_box(-1, xform=where, hx=hx, hy=hy, hz=hz, cfg=cfg)
