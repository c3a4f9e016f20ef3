"""
A clamp that follows a stream of poses (a robot's gripper) instead of the scene's motion.

Raw poses are never differentiated: the clamp tracks each new pose through a critically
damped second-order filter of bandwidth ``follow_hz`` (``omega = 2 pi follow_hz``), applied to
the translation and to the rotation vector of the turn, so that its velocity and acceleration
stay continuous and bounded (a jump ``s`` in the target accelerates the clamp by at most
``omega^2 s``). Between two poses the filter's motion is known in closed form: from the state
``x0``, ``v0`` at the last pose's time ``t0`` towards the target ``T``,

    x(t) = T + (c1 + c2 tau) exp(-omega tau),   c1 = x0 - T,   c2 = v0 + omega c1,

with ``tau = t - t0``, so the simulation asks for the clamp's frame at any time of a step,
exactly. The pose is taken relative to the first one received: a gripper at pose ``P`` carries
the clamp by ``P P0^-1``, turning it about the first pose's position.

A 2D scene follows the in-plane position and the turn about its normal; a 1D scene the
position along its axis. The clamp's frame is what :mod:`~modal_spring_ros.core.motion.frame_loads`
turns into inertial loads, as for a scene's own turning clamp.
"""
from __future__ import annotations

import math
import threading

from modal_spring_ros.core.motion.rigid_frame import RigidFrame
import numpy as np

#: Default bandwidth of the filter the clamp follows poses through, Hz.
DEFAULT_FOLLOW_HZ = 5.0
#: A quaternion whose norm is further than this from 1 is refused (not normalised).
QUATERNION_TOLERANCE = 1e-3
#: Time step of the central differences of the turn's rotation matrix, in filter time
#: constants (its rates are smooth on that scale).
_RATE_STEP = 1e-3


def rotation_vector(quaternion: np.ndarray) -> np.ndarray:
    """Axis times angle (rad, in [0, pi]) of a unit quaternion ``(x, y, z, w)``."""
    xyz, w = np.asarray(quaternion[:3], dtype=float), float(quaternion[3])
    if w < 0.0:
        xyz, w = -xyz, -w
    s = float(np.linalg.norm(xyz))
    if s < 1e-12:
        return 2.0 * xyz
    return xyz * (2.0 * math.atan2(s, w) / s)


def quaternion_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Multiply quaternions ``(x, y, z, w)``: ``a b``."""
    av, aw, bv, bw = a[:3], a[3], b[:3], b[3]
    return np.append(aw * bv + bw * av + np.cross(av, bv), aw * bw - av @ bv)


def rotation_matrix(vector: np.ndarray) -> np.ndarray:
    """Return the rotation of a rotation vector (Rodrigues)."""
    angle = float(np.linalg.norm(vector))
    if angle < 1e-12:
        k = np.zeros((3, 3))
        k[[2, 0, 1], [1, 2, 0]] = vector
        k -= k.T
        return np.eye(3) + k
    axis = vector / angle
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]],
                  [-axis[1], axis[0], 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


class ClampFollower:
    """
    The clamp's motion, following poses.

    What the engine asks of an anchor motion (:meth:`frame`, :attr:`rotates`, ...), plus
    :meth:`follow` and :meth:`check`.

    :meth:`follow` is called by the thread that steps the simulation, between two steps.
    """

    components: tuple = ()
    rotations: tuple = ()
    is_static = False

    def __init__(self, follow_hz: float, axes: tuple[int, ...], home=None,
                 reach_m: float = math.inf):
        """
        Follow poses through a filter of bandwidth ``follow_hz`` on the scene's ``axes``.

        ``home``: the clamp's rest position (world), ``reach_m``: how far from it the first pose
        may be (the clamp turns about the first pose's position: one a kilometre away would
        swing the object through kilometres).
        """
        if not (math.isfinite(follow_hz) and follow_hz > 0.0):
            raise ValueError(f'follow bandwidth ({follow_hz}) must be a positive number of Hz')
        self.follow_hz = float(follow_hz)
        self.omega = 2.0 * math.pi * self.follow_hz
        self.rotates = len(axes) >= 2
        self._mask = np.zeros(6, dtype=bool)     # translation x y z, rotation vector x y z
        self._mask[list(axes)] = True
        if len(axes) == 2:
            self._mask[3 + ({0, 1, 2} - set(axes)).pop()] = True
        elif len(axes) == 3:
            self._mask[3:] = True
        self._lock = threading.Lock()
        self.home = np.zeros(3) if home is None else np.asarray(home, dtype=float)
        self.reach_m = float(reach_m)
        self._reference: tuple[np.ndarray, np.ndarray] | None = None   # first pose
        self._accepted: tuple[np.ndarray, np.ndarray] | None = None    # last pose accepted
        self._target = np.zeros(6)
        self.revision = 0
        self.restart()

    def __getstate__(self) -> dict:
        """Picklable (a large scene's model goes to the worker process): without the lock."""
        state = dict(self.__dict__)
        del state['_lock']
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._lock = threading.Lock()

    @property
    def frequencies_hz(self) -> np.ndarray:
        """Return the motion's content: from 0 up to the filter's bandwidth."""
        return np.array([0.0, self.follow_hz])

    @property
    def rotation_frequencies_hz(self) -> np.ndarray:
        return self.frequencies_hz if self.rotates else np.empty(0)

    def to_list(self) -> list:
        return []

    # -- poses ---------------------------------------------------------------------------------
    def check(self, position, quaternion, max_jump_m: float,
              max_turn_rad: float = math.pi) -> str | None:
        """
        Why a pose is refused, or None: then it is the last pose accepted.

        Refused: non-finite values, a quaternion that is not a unit one, a first pose further
        than ``reach_m`` from the clamp's home, a jump of more than ``max_jump_m`` or a turn of
        more than ``max_turn_rad`` from the last pose *accepted* (not the last one applied: a
        stream of poses is judged pose by pose, so steps that each pass never lock it out).
        """
        position = np.asarray(position, dtype=float)
        quaternion = np.asarray(quaternion, dtype=float)
        if not (np.isfinite(position).all() and np.isfinite(quaternion).all()):
            return 'non-finite position or orientation'
        norm = float(np.linalg.norm(quaternion))
        if abs(norm - 1.0) > QUATERNION_TOLERANCE:
            return f'orientation is not a unit quaternion (norm {norm:.6g})'
        quaternion = quaternion / norm
        with self._lock:
            if self._accepted is None:
                distance = float(np.linalg.norm(position - self.home))
                if distance > self.reach_m:
                    return (f'the first pose is {distance:.3g} m from the clamp (at most '
                            f'{self.reach_m:.3g} m: the clamp turns about the first pose)')
            else:
                last_position, last_quaternion = self._accepted
                jump = float(np.linalg.norm(position - last_position))
                if jump > max_jump_m:
                    return (f'position jumps {jump:.3g} m from the last pose accepted (at most '
                            f'anchor.max_jump_m = {max_jump_m:g} m)')
                cosine = min(1.0, abs(float(quaternion @ last_quaternion)))
                turn = 2.0 * math.acos(cosine)
                if turn > max_turn_rad + 1e-12:
                    return (f'orientation turns {math.degrees(turn):.3g} degrees from the last '
                            f'pose accepted (at most anchor.max_turn_deg = '
                            f'{math.degrees(max_turn_rad):g})')
            self._accepted = (position.copy(), quaternion)
        return None

    def clear(self) -> None:
        """
        Forget every pose (``~/reset``): the clamp at its rest pose, the next pose a first one.

        Unlike :meth:`restart`, which keeps the last pose as the target.
        """
        with self._lock:
            self._reference = None
            self._accepted = None
            self._target = np.zeros(6)
            self.revision += 1
        self.restart()

    def follow(self, t: float, position, quaternion) -> None:
        """
        Track the pose ``position``.

        ``quaternion`` (x, y, z, w) from simulation time ``t`` on (the first pose is the reference
        the others are taken relative to).
        """
        position = np.asarray(position, dtype=float)
        quaternion = np.asarray(quaternion, dtype=float) / np.linalg.norm(quaternion)
        with self._lock:
            if self._reference is None:
                self._reference = (position.copy(), quaternion * [-1.0, -1.0, -1.0, 1.0])
            p0, q0_inverse = self._reference
            x, v, _ = self._state(t)
            turn = rotation_vector(quaternion_product(quaternion, q0_inverse))
            angle = float(np.linalg.norm(turn))
            if angle > 0.0:  # the same turn, one whole turn either way: nearest the clamp's
                candidates = [turn + k * (2.0 * math.pi / angle) * turn for k in (-1, 0, 1)]
                turn = min(candidates, key=lambda c: float(np.linalg.norm(c - x[3:])))
            target = np.concatenate([position - p0, turn])
            self._t0, self._x0, self._v0 = t, x, v
            self._target = np.where(self._mask, target, 0.0)
            self.revision += 1

    def restart(self) -> None:
        """
        Back at the reference pose, at rest, at t = 0 (the simulation was reset).

        The target stays, so the clamp moves to the last pose again.
        """
        with self._lock:
            self._t0 = 0.0
            self._x0 = np.zeros(6)
            self._v0 = np.zeros(6)
            self.revision += 1

    # -- the motion ----------------------------------------------------------------------------
    def _state(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Filter state (translation, rotation vector), its rate and acceleration at ``t``."""
        w, tau = self.omega, t - self._t0
        c1 = self._x0 - self._target
        c2 = self._v0 + w * c1
        e = math.exp(-w * tau)
        lag = c1 + c2 * tau
        return (self._target + lag * e, (c2 - w * lag) * e, (w * w * lag - 2.0 * w * c2) * e)

    def frame(self, t: float) -> RigidFrame:
        with self._lock:
            x, v, a = self._state(t)
            h = _RATE_STEP / self.omega
            before, after = self._state(t - h)[0], self._state(t + h)[0]
            pivot = self._reference[0] if self._reference is not None else np.zeros(3)
        r = rotation_matrix(x[3:])
        r0, r1 = rotation_matrix(before[3:]), rotation_matrix(after[3:])
        dr = (r1 - r0) / (2.0 * h)
        ddr = (r1 - 2.0 * r + r0) / (h * h)
        return RigidFrame(r, dr, ddr, pivot - r @ pivot + x[:3], v[:3] - dr @ pivot,
                          a[:3] - ddr @ pivot)

    def offset(self, t: float) -> np.ndarray:
        return self.frame(t).translation

    def velocity(self, t: float) -> np.ndarray:
        return self.frame(t).velocity

    def acceleration(self, t: float) -> np.ndarray:
        return self.frame(t).acceleration
