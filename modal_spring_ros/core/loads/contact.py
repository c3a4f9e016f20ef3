"""
Contact with the scene's colliders: a penalty normal force and Coulomb friction, per particle.

A free particle inside a collider (:mod:`~modal_spring_ros.core.model.colliders`) by a depth
``delta`` is pushed out along the collider's normal by ``k delta + c (delta - delta_last) / dt``
(never pulling). Friction holds it where it first touched: a tangential spring of the same
``k`` and damping to a stick point, up to ``static_friction`` times the normal force; beyond,
the particle slides with ``sliding_friction`` times the normal force against its slip, and the
stick point follows it. Every particle is its own contact point, every collider on its own (a
particle in two colliders is pushed by both). A collider attached to a frame is measured in
that frame (:meth:`ContactLoad.moved` sets its pose): its stick points ride with it, so a
moving finger carries what it holds.

The contact's stiffness is the run's (below its full run's step, the full run's:
:func:`finest_step`): each particle's ``k = m (c / dt)^2``, with ``c`` what the
explicit step leaves beside the fastest coordinate the run steps (``sqrt(1.2^2 - (omega dt)^2)``,
at most 0.5 and at least 0.2): stiff at the run's step without making it unstable; under an
implicit step, :data:`IMPLICIT_RATE` (its iteration's fixed tangent leaves contact out). A particle
pressed with a force ``F`` sinks ``F / k = F dt^2 / (m c^2)``: with ``c = 0.5`` and gravity alone,
``4 g dt^2`` (10 micrometres at 0.5 ms), the stated bound. The damping is critical (half of it
under an implicit step), on the depth's change since the last step (no velocity needed; a run
in any coordinates can step it).
Why not stiffer: at ``c`` near 1 the explicit step resolves a touch within a step and throws
the particle back at its depth over the step, whatever the damping (a particle dropped 5 cm
onto a plane rebounded to 4.6 cm at ``c = 1``, 3.5 cm at 0.7); at 0.5, critically damped, the
touch lasts several steps and the damping takes its energy (a rebound to 2 mm).

A penalty that resolves a depth in about a step would throw out a particle found deep inside (a
scene that starts overlapping a collider, a collider moved or added into the object) at the
depth over the step: 2.7 cm at 0.17 ms is 160 m/s. So depth beyond ``V_OUT dt / c^2`` (what the
penalty pushes out at ``V_OUT`` in a step; millimetres, against micrometres at rest) counts as
that much, to the spring and to the damping alike, and a particle moving out faster than
``V_OUT`` is held back to it: a deep particle leaves at ``V_OUT``, as physics engines bound their
depenetration speed. A particle hitting faster than ``V_OUT`` is stopped over a few steps
instead of one (a particle at 5 m/s under a 1 ms step stays within the 10 mm half-thickness of
a box: tested).

What a step changes (the stick points, the depths) the load keeps: after each step the run
replaces it by :meth:`ContactLoad.stepped`, as the contract allows
(:attr:`~modal_spring_ros.core.loads.base.Load.keeps_state`).
"""
from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

from modal_spring_ros.core.loads.base import Load, WorldPositions
from modal_spring_ros.core.model.colliders import Contact, Pose
import numpy as np

#: what the explicit step may take in all (``omega dt`` of the fastest coordinate and contact)
STEP_SHARE = 1.2
#: the contact's own ``omega dt``: at least, and at most
CONTACT_RATE = (0.2, 0.5)
#: a gripper's hold's ``omega dt`` at most (it holds, it never lands: stiffer does not bounce),
#: and its damping, a share of critical
HOLD_RATE, HOLD_DAMPING_RATIO = 1.0, 0.5
#: the contact's ``omega dt`` under an implicit step (whose fixed tangent leaves contact out):
#: each iteration then shrinks a contact force's change to about ``(rate^2 + rate) / 4`` of it
IMPLICIT_RATE = 0.4
#: the normal damping, a share of critical: under the explicit step, and under an implicit step
#: (whose fixed-tangent iteration stops converging on a sliding particle with more)
DAMPING_RATIO, IMPLICIT_DAMPING_RATIO = 1.0, 0.5
#: the fastest a particle is pushed out of a collider, m/s
V_OUT = 3.0


@dataclasses.dataclass(frozen=True, eq=False)
class ContactLoad(Load):
    """A scene's contact on the free particles: forces from their world positions."""

    name: ClassVar[str] = 'contact'
    keeps_state: ClassVar[bool] = True
    contact: Contact
    stiffness: np.ndarray        # (free,) N/m
    damping: np.ndarray          # (free,) N s/m
    mass: np.ndarray             # (free,) kg
    dt: float
    anchors: np.ndarray          # (colliders, free, 3) stick points, NaN where not touching
    depths: np.ndarray           # (colliders, free) depth at the last step (0: outside)
    slips: np.ndarray            # (colliders, free, 3) tangential offset from the stick point
    until: float = math.inf
    #: where each collider is: None for one fixed in the world, else its frame's pose (None
    #: while an attached collider's frame is not known yet: it is not there to touch)
    poses: tuple = ()
    #: the last evaluation, (points, each touched collider's (index, inside, depth, forces,
    #: stick points, offsets)): the step's forces and its end are taken at the same points,
    #: so each collider's distances are found once a step
    _last: tuple = dataclasses.field(init=False, default=(None, ()), compare=False,
                                     repr=False)

    # -- what the contract asks ----------------------------------------------------------------
    def world_forces(self, model, world_positions: WorldPositions, t: float):
        points, slots = self._points(model, world_positions)
        forces = np.zeros_like(points)
        touching = np.zeros(len(points), dtype=bool)
        for _, inside, _, f, _, _ in self._touches(points):
            forces[inside] += f
            touching[inside] = True
        if not touching.any():
            return None
        which = np.flatnonzero(touching)
        d = model.dimension
        dofs = (slots[which, None] * d + np.arange(d)).ravel()
        return dofs, forces[which][:, list(model.axes)].ravel()

    def stepped(self, model, world_positions: WorldPositions, t: float) -> 'ContactLoad':
        """Return the load after a step: new stick points (slid ones moved) and depths."""
        points, _ = self._points(model, world_positions)
        anchors = np.full_like(self.anchors, np.nan)
        depths = np.zeros_like(self.depths)
        slips = np.zeros_like(self.slips)
        for c, inside, depth, _, anchor, slip in self._touches(points):
            anchors[c, inside], slips[c, inside], depths[c, inside] = anchor, slip, depth
        return dataclasses.replace(self, anchors=anchors, depths=depths, slips=slips)

    def moved(self, frame: str, pose: Pose) -> 'ContactLoad':
        """Return the load with the colliders attached to ``frame`` where ``pose`` puts them."""
        poses = list(self._poses())
        for c in range(len(poses)):
            if self.contact.frame(c) == frame:
                poses[c] = pose
        return dataclasses.replace(self, poses=tuple(poses))

    def placed_as(self, other: 'ContactLoad | None') -> 'ContactLoad':
        """Return the load with ``other``'s colliders' poses (a reset keeps where they are)."""
        if other is None or other.contact is not self.contact:
            return self
        return dataclasses.replace(self, poses=other.poses)

    def _poses(self) -> tuple:
        return self.poses or (None,) * len(self.contact.colliders)

    def _touches(self, points: np.ndarray) -> tuple:
        """
        Return what touches at ``points``: the last evaluation's if at the same points.

        Each collider measures in its own frame (the world's, or its pose's): its stick points
        are kept there, so a moving collider carries what it holds, and its friction and
        damping act on the motion relative to it; the forces are turned back into the world.
        """
        last_points, touches = self._last          # one read: another run may replace it
        if last_points is not None and np.array_equal(last_points, points):
            return touches
        touches = []
        for c, (collider, pose) in enumerate(zip(self.contact.colliders, self._poses())):
            if pose is None and self.contact.frame(c):
                continue                           # attached to a frame not known yet
            local = points if pose is None else pose.into_frame(points)
            distance, normal = collider.distance(local)
            inside = np.flatnonzero(distance < 0.0)
            if inside.size:
                depth = -distance[inside]
                force, anchor, slip = self._at(c, inside, local[inside], depth, normal[inside])
                touches.append((c, inside, depth,
                                force if pose is None else pose.to_world(force), anchor, slip))
        touches = tuple(touches)
        object.__setattr__(self, '_last', (points, touches))
        return touches

    # -- the arithmetic ------------------------------------------------------------------------
    def _points(self, model, world_positions: WorldPositions) -> tuple[np.ndarray, np.ndarray]:
        """Return every free particle's world position in 3D, and their slots."""
        slots = np.arange(model.free_particles.size)
        return free_points(model, world_positions), slots

    def _at(self, c: int, idx: np.ndarray, x: np.ndarray, depth: np.ndarray,
            normal: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """
        Return forces on particles ``idx`` inside collider ``c``, stick points, offsets.

        The offsets: each particle's tangential offset from its stick point. Normal and held
        tangential motion are damped alike, on their change since the last step.
        """
        k, damp, mass = self.stiffness[idx], self.damping[idx], self.mass[idx]
        last = self.depths[c, idx]
        cap = V_OUT * mass / (k * self.dt)             # V_OUT dt / c^2
        held, was = np.minimum(depth, cap), np.minimum(last, cap)
        pressed = k * held + damp * (held - was) / self.dt
        out = (last - depth) / self.dt                 # moving out, m/s
        pressed -= mass / self.dt * np.maximum(out - V_OUT, 0.0)
        pressed = np.maximum(pressed, 0.0)
        anchor = self.anchors[c, idx]
        new = np.isnan(anchor[:, 0])
        anchor = np.where(new[:, None], x, anchor)       # first touch: held where it touched
        slip = x - anchor
        slip -= np.sum(slip * normal, axis=1, keepdims=True) * normal
        length = np.linalg.norm(slip, axis=1)
        rate = (slip - np.where(new[:, None], slip, self.slips[c, idx])) / self.dt
        held = k * length <= self.contact.static_friction * pressed   # stick spring within
        trial = -k[:, None] * slip - damp[:, None] * rate                # static friction
        sliding = self.contact.sliding_friction * pressed
        unit = np.divide(slip, length[:, None], out=np.zeros_like(slip),
                         where=length[:, None] > 0.0)
        friction = np.where(held[:, None], trial, -sliding[:, None] * unit)
        # a sliding particle's stick point follows it, as far behind as sliding friction pulls
        behind = np.divide(sliding, k)[:, None] * unit
        anchor = np.where(held[:, None], anchor, x - behind)
        slip = np.where(held[:, None], slip, behind)
        return pressed[:, None] * normal + friction, anchor, slip

    # -- what a run reports ----------------------------------------------------------------------
    @property
    def touching(self) -> int:
        """Return how many particles touched a collider at the last step."""
        return int(np.count_nonzero((self.depths > 0.0).any(axis=0)))

    @property
    def deepest(self) -> float:
        """Return the deepest penetration at the last step, m."""
        return float(self.depths.max(initial=0.0))

    def describe(self) -> str:
        """Return what touches, as text (``3 particles touching, deepest 2.5e-06 m``)."""
        return f'{self.touching} particles touching, deepest {self.deepest:.3g} m'


def penalty(model, dt: float, stability_limit: float,
            hold: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the stiffness and damping of a penalty on each free particle for a run's step.

    ``k = m (c / dt)^2``, ``c`` what the explicit step leaves beside the fastest coordinate
    stepped (``stability_limit``: ``2 / omega``; inf for an implicit step, which takes
    :data:`IMPLICIT_RATE`), at most ``CONTACT_RATE``'s; critical damping (half under an implicit
    step). A gripper's ``hold`` is a spring that never lets go, not a touch that could bounce:
    up to :data:`HOLD_RATE`, half-critically damped, it holds four times as stiffly.
    """
    # an implicit step takes what its fixed-tangent iteration converges with
    explicit = math.isfinite(stability_limit)
    most = HOLD_RATE if hold else CONTACT_RATE[1]
    rate = _rate(2.0 * dt / stability_limit, most) if explicit else IMPLICIT_RATE
    ratio = (HOLD_DAMPING_RATIO if hold else DAMPING_RATIO if explicit
             else IMPLICIT_DAMPING_RATIO)
    mass = particle_masses(model)
    # at a step finer than the full run's own, the full run's contact (:func:`finest_step`)
    floor = finest_step(model)
    finest = ((_rate(floor * model.omega_bound, most) / floor) ** 2 if math.isfinite(floor)
              else math.inf)
    stiffness = mass * min((rate / dt) ** 2, finest)
    return stiffness, 2.0 * ratio * np.sqrt(stiffness * mass)


def particle_masses(model) -> np.ndarray:
    """Return each free particle's mass, kg."""
    return model.mass_dof.reshape(-1, model.dimension)[:, 0]


def finest_step(model) -> float:
    """
    Return the step below which contact is the same whatever a run's step: the full run's.

    The scene's step, or half the full explicit run's stability limit (``1 / omega``, from the
    bound :attr:`~modal_spring_ros.core.model.model.MassSpringModel.omega_bound`). A penalty
    tuned to each step would stiffen four times at each halving: runs at ever finer steps would
    be ever different physics, and a step-doubled reference (the automatic choice's, the
    benchmarks') would never converge. Below this step the penalty is the full run's at it.
    """
    omega = model.omega_bound
    return model.scene.default_dt or (1.0 / omega if omega > 0.0 else math.inf)


def _rate(omega_dt: float, most: float) -> float:
    """Return the penalty's ``omega dt`` beside a coordinate at ``omega_dt`` (``c``), at most."""
    return min(most, max(CONTACT_RATE[0],
                         math.sqrt(max(STEP_SHARE ** 2 - omega_dt ** 2, 0.0))))


def free_points(model, world_positions, slots: np.ndarray | None = None) -> np.ndarray:
    """Return the world positions in 3D of the free particles at ``slots`` (None: all)."""
    if model.dimension == 3:
        return world_positions(slots)
    free = model.free_particles if slots is None else model.free_particles[slots]
    points = model.scene.rest_positions[free].astype(float)
    points[:, list(model.axes)] = world_positions(slots)
    return points


def contact_load(model, contact: Contact, dt: float, stability_limit: float,
                 state: ContactLoad | None = None) -> ContactLoad:
    """
    Return the contact of ``model`` for a run stepping at ``dt``.

    ``stability_limit``: the explicit step's limit of what the run steps (``2 / omega``; inf
    when nothing limits it). ``state``: a contact whose stick points and depths go on (a run
    that takes over from another).
    """
    stiffness, damping = penalty(model, dt, stability_limit)
    mass = particle_masses(model)
    shape = (len(contact.colliders), stiffness.size)
    poses = ()
    if state is not None and state.depths.shape == shape:
        anchors, depths, slips, poses = state.anchors, state.depths, state.slips, state.poses
    else:       # at rest: what rests on a collider is held where it rests, and as deep
        anchors, depths = np.full(shape + (3,), np.nan), np.zeros(shape)
        slips = np.zeros(shape + (3,))
        rest = model.scene.rest_positions[model.free_particles]
        for c, collider in enumerate(contact.colliders):
            if contact.frame(c):
                continue                           # attached: where, TF will say
            distance = collider.distance(rest)[0]
            inside = distance < 0.0
            anchors[c, inside], depths[c, inside] = rest[inside], -distance[inside]
    return ContactLoad(contact, stiffness, damping, mass, float(dt), anchors, depths, slips,
                       poses=poses)
