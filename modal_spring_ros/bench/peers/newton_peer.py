"""
Newton as a peer: a scene's mass-spring system stepped by Newton's semi-implicit solver.

Newton (``pip install newton``, Apache-2.0, on NVIDIA Warp) is the physics engine robotics
simulators build on; its ``SolverSemiImplicit`` on the CPU is the explicit method a user would
otherwise run. :class:`NewtonRun` builds the same particles, masses, springs (stiffness and rest
length), gravity and clamp as the scene (Newton's own float32 state), steps it as Newton's
examples do, and offers what :func:`~modal_spring_ros.core.auto.measured_error.trajectory` and
the benchmarks' timing read of a run (``dt``, ``model``, ``reset``, ``step``, ``displacement``):
the free particles' displacement from rest in the clamp's frame.

What the scene has and Newton's solver has not is refused (:class:`PeerRefused`): a turning clamp,
modal damping ratios, another spring law, bending, colliders it cannot place. Mass-proportional
Rayleigh damping is a force ``-alpha m v`` (``v`` relative to the clamp, as the core damps) written
into the particles' force buffer before each step (where Newton's examples clear it); the
stiffness-proportional term is each spring's damping ``kd = beta k`` (the same damping on the
springs' material stiffness). Contact between particles is switched off (the core has none); the
scene's colliders are Newton shapes the particles touch
(:mod:`~modal_spring_ros.bench.peers.newton_contact`). Newton is optional: without it
:data:`AVAILABLE` is false and :data:`MISSING` says how to install it.
"""
from __future__ import annotations

from modal_spring_ros.bench.peers.newton_contact import contact_refusal, NewtonContact
from modal_spring_ros.core.laws import DEFAULT_LAW
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.model.scene import Scene
import numpy as np

try:
    import warp as wp
    # no start-up banner or kernel-load lines in the benchmark's output (set before Newton)
    wp.config.quiet = True
    wp.config.log_level = wp.LOG_WARNING
    import newton  # noqa: E402, I100
except ImportError:     # the optional 'peer' extra is not installed
    newton = wp = None

#: Newton is installed
AVAILABLE = newton is not None
#: what the benchmark says where it is not
MISSING = ("Newton is not installed (pip install '.[peer]', or pip install newton): "
           'the peer rows are skipped')


class PeerRefused(ValueError):
    """A scene Newton's semi-implicit solver cannot run as the project does; says why."""


if AVAILABLE:
    @wp.kernel
    def _before_step(fixed: wp.array(dtype=wp.int32), rest: wp.array(dtype=wp.vec3),
                     offsets: wp.array(dtype=wp.vec3), velocities: wp.array(dtype=wp.vec3),
                     index: wp.array(dtype=wp.int32), mass_alpha: wp.array(dtype=float),
                     q: wp.array(dtype=wp.vec3), qd: wp.array(dtype=wp.vec3),
                     force: wp.array(dtype=wp.vec3)):
        """
        Put clamped particles where the clamp is, moving as it does; start the free ones'.

        forces with ``-alpha m (v - v_clamp)`` (zero without mass damping). The clamp's pose
        at this step is ``offsets[index[0]]`` (a captured graph replays the same launch at
        every step). One launch a step.
        """
        tid = wp.tid()
        k = index[0]
        velocity = velocities[k]
        if fixed[tid] != 0:
            q[tid] = rest[tid] + offsets[k]
            qd[tid] = velocity
            force[tid] = wp.vec3(0.0, 0.0, 0.0)
        else:
            force[tid] = -mass_alpha[tid] * (qd[tid] - velocity)

    @wp.kernel
    def _count_step(index: wp.array(dtype=wp.int32)):
        """Count the step: its index one up."""
        index[0] = index[0] + 1


def refusal(scene: Scene) -> str:
    """Return why Newton's semi-implicit solver cannot run ``scene`` as the project does, or ''."""
    if scene.anchor_motion.rotates:
        return 'the clamp turns (the peer moves clamps that translate)'
    if scene.damping.ratio:
        return 'modal damping ratios have no counterpart in physical coordinates'
    if scene.spring_law != DEFAULT_LAW:
        return f"its springs' law is '{scene.spring_law}' (Newton's springs are linear)"
    if scene.bending is not None and scene.bending.count:
        return "it bends (the peer's object is springs alone)"
    return contact_refusal(scene)


class NewtonRun:
    """
    A scene stepped by Newton's ``SolverSemiImplicit`` at ``dt`` on the CPU.

    As a Newton user steps it: two steps (from one state into the other and back) captured once
    as a Warp graph and replayed (``graph``, the default: Warp 1.13 and later replay graphs on
    the CPU); an odd step is launched as it comes. The clamp's pose at every step is computed
    ahead into arrays the graph reads by a step counter kept in Warp.

    :raises PeerRefused: a scene the peer cannot run (:func:`refusal`).
    :raises RuntimeError: Newton is not installed.
    """

    def __init__(self, scene: Scene, dt: float, graph: bool = True):
        if not AVAILABLE:
            raise RuntimeError(MISSING)
        reason = refusal(scene)
        if reason:
            raise PeerRefused(f"scene '{scene.name}': {reason}")
        self.scene, self.dt = scene, float(dt)
        self.model = MassSpringModel(scene)
        self.coordinates = 3 * scene.n_particles
        builder = newton.ModelBuilder(gravity=tuple(float(g) for g in scene.gravity))
        builder.add_particles(pos=[tuple(p) for p in scene.rest_positions],
                              vel=[(0.0, 0.0, 0.0)] * scene.n_particles,
                              mass=np.where(scene.fixed, 0.0, scene.mass).tolist(),
                              radius=[0.0] * scene.n_particles)     # points, as the core's
        self._contact = None if scene.contact is None else NewtonContact(builder, scene, dt)
        beta = float(scene.damping.rayleigh_beta)
        for (i, j), k in zip(scene.springs.tolist(), np.asarray(scene.stiffness).tolist()):
            builder.add_spring(i, j, k, beta * k, 0.0)
        self._newton = builder.finalize(device='cpu')
        self._newton.particle_grid = None       # no contact between particles: the core has none
        if self._contact is not None:
            self._contact.finalize(self._newton)
        self._newton.spring_rest_length.assign(np.asarray(scene.rest_length, dtype=np.float32))
        self._solver = newton.solvers.SolverSemiImplicit(self._newton)
        self._control = self._newton.control()  # made once, as Newton's examples do
        self._mass_alpha = wp.array(float(scene.damping.rayleigh_alpha)
                                    * np.where(scene.fixed, 0.0, scene.mass), dtype=float,
                                    device='cpu')
        self._fixed = wp.array(scene.fixed.astype(np.int32), dtype=wp.int32, device='cpu')
        self._rest = wp.array(scene.rest_positions, dtype=wp.vec3, device='cpu')
        self._free = np.flatnonzero(~scene.fixed)
        self._index = wp.zeros(1, dtype=wp.int32, device='cpu')
        self._state, self._next = self._newton.state(), self._newton.state()
        self._offsets = self._velocities = None
        self.graph = bool(graph) and hasattr(wp, 'capture_launch')
        self._graph = None
        self.reset()

    def reset(self) -> None:
        """Go back to rest at t = 0."""
        rest = self._newton.state()
        for name in ('particle_q', 'particle_qd', 'particle_f'):
            for state in (self._state, self._next):
                wp.copy(getattr(state, name), getattr(rest, name))
        self._index.zero_()
        self.steps = 0

    @property
    def time(self) -> float:
        return self.steps * self.dt

    def step(self, n: int = 1) -> None:
        """Advance ``n`` steps: the clamp placed at the step's start, then Newton's step."""
        self._reach(self.steps + n)
        pairs, odd = divmod(n, 2)
        for _ in range(pairs):
            if self._graph is not None:
                wp.capture_launch(self._graph)
            else:
                self._two_steps()
        if odd:     # into the other state, and back where the graph reads it
            self._one_step(self._state, self._next)
            for name in ('particle_q', 'particle_qd'):
                wp.copy(getattr(self._state, name), getattr(self._next, name))
        self.steps += n

    def displacement(self) -> np.ndarray:
        """Free-DOF displacement from rest in the clamp's frame (the core's order), float64."""
        x = self._state.particle_q.numpy().astype(float)
        offset = self.scene.anchor_motion.offset(self.time)
        u = x - self.scene.rest_positions - offset
        return u[self._free][:, self.model.axes].reshape(-1)

    # -- internals -----------------------------------------------------------------------------
    def _one_step(self, state, into) -> None:
        wp.launch(_before_step, dim=self.scene.n_particles, device='cpu',
                  inputs=[self._fixed, self._rest, self._offsets, self._velocities, self._index,
                          self._mass_alpha],
                  outputs=[state.particle_q, state.particle_qd, state.particle_f])
        contacts = None if self._contact is None else self._contact.collide(state)
        self._solver.step(state, into, self._control, contacts, self.dt)
        wp.launch(_count_step, dim=1, device='cpu', inputs=[self._index])

    def _two_steps(self) -> None:
        self._one_step(self._state, self._next)
        self._one_step(self._next, self._state)

    def _reach(self, steps: int) -> None:
        """Have the clamp's pose for every step below ``steps`` (and the graph reading it)."""
        have = 0 if self._offsets is None else self._offsets.shape[0]
        if steps <= have:
            return
        size = max(1024, 2 * have, steps)
        motion = self.scene.anchor_motion
        times = self.dt * np.arange(size)
        self._offsets = wp.array(np.array([motion.offset(t) for t in times]), dtype=wp.vec3,
                                 device='cpu')
        self._velocities = wp.array(np.array([motion.velocity(t) for t in times]),
                                    dtype=wp.vec3, device='cpu')
        if self.graph:
            index = self._index.numpy().copy()
            with wp.ScopedCapture(device='cpu') as capture:
                self._two_steps()
            self._graph = capture.graph
            self._index.assign(index)      # capturing ran nothing (or ran it: set it back)
