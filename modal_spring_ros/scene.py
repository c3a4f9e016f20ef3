"""Scenes: particles, springs, fixed particles, loads and damping, loaded from YAML and validated.

A scene file is YAML in SI units. Particles and springs are given either explicitly or by a
lattice generator; see ``README.md`` ("Scene files") for the full format. Every problem found on
load raises :class:`SceneError` with a message that names the field and the problem, so that
command-line tools can print it instead of a traceback.

This module has no ROS dependency.
"""
from __future__ import annotations

import dataclasses
import itertools
import math
import sys
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import yaml

from modal_spring_ros.anchor_motion import AnchorMotion, SineComponent

PACKAGE_NAME = "modal_spring_ros"


def share_directory() -> Path:
    """The package's data folder (``config/`` lives there).

    A source checkout or editable install uses the repository itself; an installed package uses
    ``<prefix>/share/modal_spring_ros`` (found with ament_index on a ROS install, or under the
    Python prefix for a pip install into a venv).
    """
    source = Path(__file__).resolve().parent.parent
    if (source / "config" / "scenes").is_dir():
        return source
    try:
        from ament_index_python.packages import get_package_share_directory
        return Path(get_package_share_directory(PACKAGE_NAME))
    except Exception:  # not on an ament index: fall back to the Python prefix
        return Path(sys.prefix) / "share" / PACKAGE_NAME


def builtin_scene_dir() -> Path:
    """Folder holding the built-in scene files."""
    return share_directory() / "config" / "scenes"

#: The scene used when none is named.
DEFAULT_SCENE = "sheet_10x10"

_AXES = {"x": 0, "y": 1, "z": 2}


class SceneError(ValueError):
    """An invalid scene: the message names the source, the field and the problem."""


@dataclasses.dataclass(frozen=True)
class Damping:
    """Damping of a scene: the paper's modal ratio ``h`` and/or Rayleigh ``alpha M + beta K``.

    Modal damping of mode ``i`` is ``C_i = 2 h omega_i + alpha + beta omega_i**2`` (with
    mass-normalised modes).
    """

    ratio: float = 0.0
    rayleigh_alpha: float = 0.0
    rayleigh_beta: float = 0.0

    def modal_coefficients(self, omega: np.ndarray) -> np.ndarray:
        """``C_i`` for circular frequencies ``omega`` (rad/s)."""
        omega = np.asarray(omega, dtype=float)
        return 2.0 * self.ratio * omega + self.rayleigh_alpha + self.rayleigh_beta * omega**2

    @property
    def is_zero(self) -> bool:
        return self.ratio == 0.0 and self.rayleigh_alpha == 0.0 and self.rayleigh_beta == 0.0


@dataclasses.dataclass(frozen=True, eq=False)
class Scene:
    """A validated mass-spring scene. Arrays are read-only.

    Attributes:
        name: scene name (file stem for scene files).
        dimension: 1 (motion along ``axis`` only, the paper's chain), 2 (motion in the x-y
            plane, z stays at rest) or 3.
        axes: the world axes that move (0 = x, 1 = y, 2 = z), ``dimension`` of them.
        rest_positions: (n, 3) particle positions at rest (springs at their rest length).
        mass: (n,) particle masses, kg.
        springs: (E, 2) particle index pairs, i < j.
        stiffness: (E,) spring stiffness, N/m.
        rest_length: (E,) spring rest length, m (distance at rest).
        fixed: (n,) bool, particles that follow the prescribed anchor motion.
        gravity: (3,) gravitational acceleration, m/s^2.
        damping: the scene's damping.
        anchor_motion: prescribed motion of the fixed particles.
        default_dt: suggested time step, s (None: chosen from the modes).
        default_duration: suggested run length, s.
        description: free text.
    """

    name: str
    dimension: int
    axes: tuple[int, ...]
    rest_positions: np.ndarray
    mass: np.ndarray
    springs: np.ndarray
    stiffness: np.ndarray
    rest_length: np.ndarray
    fixed: np.ndarray
    gravity: np.ndarray
    damping: Damping = Damping()
    anchor_motion: AnchorMotion = AnchorMotion(())
    default_dt: float | None = None
    default_duration: float = 5.0
    description: str = ""

    @property
    def n_particles(self) -> int:
        return int(self.rest_positions.shape[0])

    @property
    def n_springs(self) -> int:
        return int(self.springs.shape[0])

    @property
    def n_free_dof(self) -> int:
        return int((~self.fixed).sum()) * self.dimension

    def surface_triangles(self) -> np.ndarray:
        """(T, 3) particle triangles of the scene's surface, empty when it has none.

        A 2D lattice sheet is a surface (two triangles per cell, taken from its diagonal
        springs' cells); scenes without that structure return an empty array.
        """
        return _lattice_triangles(self)

    def to_dict(self) -> dict[str, Any]:
        """The full, explicit definition (loadable by :func:`scene_from_dict`)."""
        return {
            "name": self.name,
            "description": self.description,
            "dimension": self.dimension,
            **({"axis": "xyz"[self.axes[0]]} if self.dimension == 1 else {}),
            "particles": {
                "positions": self.rest_positions.tolist(),
                "mass": self.mass.tolist(),
            },
            "springs": {
                "pairs": self.springs.tolist(),
                "stiffness": self.stiffness.tolist(),
            },
            "fixed": {"indices": np.flatnonzero(self.fixed).tolist()},
            "gravity": self.gravity.tolist(),
            "damping": {
                "ratio": self.damping.ratio,
                "rayleigh": {
                    "alpha": self.damping.rayleigh_alpha,
                    "beta": self.damping.rayleigh_beta,
                },
            },
            "anchor_motion": self.anchor_motion.to_list(),
            "simulation": {"dt": self.default_dt, "duration": self.default_duration},
        }

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.to_dict(), sort_keys=False)


# --------------------------------------------------------------------------------------------
# Loading


def builtin_scene_names() -> list[str]:
    """Names of the scenes shipped with the package."""
    return sorted(p.stem for p in builtin_scene_dir().glob("*.yaml"))


def load_scene(name_or_path: str | Path) -> Scene:
    """Load a built-in scene by name, or a scene file by path.

    Raises:
        SceneError: unknown name, unreadable file, invalid YAML or an invalid scene.
    """
    text = str(name_or_path)
    path = Path(text)
    if not (text.endswith((".yaml", ".yml")) or path.exists()):
        candidate = builtin_scene_dir() / f"{text}.yaml"
        if not candidate.exists():
            raise SceneError(
                f"unknown scene '{text}': not a file, and not a built-in scene "
                f"(built-in: {', '.join(builtin_scene_names())})"
            )
        path = candidate
    try:
        raw = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SceneError(f"{path}: cannot read scene file: {exc.strerror or exc}") from None
    return scene_from_yaml(raw, source=str(path), default_name=path.stem)


def scene_from_yaml(text: str, source: str = "<scene>", default_name: str = "scene") -> Scene:
    """Parse and validate a scene from YAML text."""
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise SceneError(f"{source}: invalid YAML: {exc}") from None
    return scene_from_dict(data, source=source, default_name=default_name)


def scene_from_dict(data: Any, source: str = "<scene>", default_name: str = "scene") -> Scene:
    """Validate a scene given as a mapping (the parsed YAML)."""
    return _SceneParser(source).parse(data, default_name)


class _SceneParser:
    def __init__(self, source: str):
        self.source = source

    def fail(self, field: str, problem: str) -> SceneError:
        return SceneError(f"{self.source}: {field}: {problem}")

    # -- small typed getters ------------------------------------------------------------------
    def mapping(self, value: Any, field: str) -> Mapping[str, Any]:
        if not isinstance(value, Mapping):
            raise self.fail(field, f"must be a mapping, got {type(value).__name__}")
        return value

    def number(self, value: Any, field: str, *, positive: bool = False,
               non_negative: bool = False) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(field, f"must be a number, got {value!r}")
        value = float(value)
        if not math.isfinite(value):
            raise self.fail(field, f"must be finite, got {value}")
        if positive and value <= 0.0:
            raise self.fail(field, f"must be positive, got {value:g}")
        if non_negative and value < 0.0:
            raise self.fail(field, f"must not be negative, got {value:g}")
        return value

    def per_item(self, value: Any, count: int, field: str, what: str) -> np.ndarray:
        """A positive scalar broadcast to ``count`` items, or a list of ``count`` of them."""
        if isinstance(value, (list, tuple)):
            if len(value) != count:
                raise self.fail(field, f"has {len(value)} values for {count} {what}")
            arr = np.array([self.number(v, f"{field}[{i}]") for i, v in enumerate(value)])
        else:
            arr = np.full(count, self.number(value, field))
        bad = np.flatnonzero(arr <= 0.0)
        if bad.size:
            i = int(bad[0])
            name = f"{field}[{i}]" if isinstance(value, (list, tuple)) else field
            raise self.fail(name, f"must be positive, got {arr[i]:g}"
                            + (f" ({bad.size} {what} affected)" if bad.size > 1 else ""))
        return arr

    def vector3(self, value: Any, field: str) -> np.ndarray:
        if not isinstance(value, (list, tuple)) or len(value) not in (2, 3):
            raise self.fail(field, f"must be a list of 2 or 3 numbers, got {value!r}")
        out = np.zeros(3)
        for i, v in enumerate(value):
            out[i] = self.number(v, f"{field}[{i}]")
        return out

    # -- the scene ----------------------------------------------------------------------------
    def parse(self, data: Any, default_name: str) -> Scene:
        data = self.mapping(data, "scene")
        known = {"name", "description", "dimension", "axis", "particles", "springs", "fixed", "gravity",
                 "damping", "anchor_motion", "simulation"}
        unknown = sorted(set(data) - known)
        if unknown:
            raise self.fail(unknown[0], f"unknown key (known keys: {', '.join(sorted(known))})")
        name = str(data.get("name", default_name))
        dimension = data.get("dimension", 2)
        if dimension not in (1, 2, 3) or isinstance(dimension, bool):
            raise self.fail("dimension", f"must be 1, 2 or 3, got {dimension!r}")
        if dimension == 1:
            axis = data.get("axis", "x")
            if axis not in _AXES:
                raise self.fail("axis", f"must be x, y or z, got {axis!r}")
            axes = (_AXES[axis],)
        elif "axis" in data:
            raise self.fail("axis", "only a 1D scene (dimension: 1) has an axis")
        else:
            axes = tuple(range(dimension))

        particles = self.mapping(self.required(data, "particles", "scene"), "particles")
        positions, lattice = self.positions(particles, dimension)
        if lattice is not None and dimension == 1 and axes[0] != 0:
            positions[:, [0, axes[0]]] = positions[:, [axes[0], 0]]
        n = positions.shape[0]
        mass = self.per_item(self.required(particles, "mass", "particles"), n,
                             "particles.mass", "particles")

        springs_spec = self.mapping(self.required(data, "springs", "scene"), "springs")
        pairs = self.pairs(springs_spec, n, lattice)
        stiffness = self.per_item(self.required(springs_spec, "stiffness", "springs"),
                                  len(pairs), "springs.stiffness", "springs")
        rest_length = self.check_springs(pairs, positions)
        fixed = self.fixed(data.get("fixed"), positions)
        self.check_connected(pairs, n)

        gravity = self.vector3(data.get("gravity", [0.0, 0.0, 0.0]), "gravity")
        still = [a for a in range(3) if a not in axes]
        if np.any(gravity[still] != 0.0):
            raise self.fail("gravity", f"a {dimension}D scene moves along "
                            f"{', '.join('xyz'[a] for a in axes)} only: gravity must be 0 along "
                            f"{', '.join('xyz'[a] for a in still)}")
        if np.any(positions[:, still] != positions[0, still]):
            raise self.fail("particles", f"a {dimension}D scene must have equal "
                            f"{', '.join('xyz'[a] for a in still)} for every particle")

        damping = self.damping(data.get("damping", {}))
        anchor_motion = self.anchor_motion(data.get("anchor_motion", []), axes)
        sim = self.mapping(data.get("simulation", {}) or {}, "simulation")
        dt = sim.get("dt")
        default_dt = None if dt is None else self.number(dt, "simulation.dt", positive=True)
        duration = self.number(sim.get("duration", 5.0), "simulation.duration", positive=True)

        def frozen(a: np.ndarray) -> np.ndarray:
            a.setflags(write=False)
            return a

        return Scene(
            name=name,
            dimension=int(dimension),
            axes=axes,
            rest_positions=frozen(positions),
            mass=frozen(mass),
            springs=frozen(pairs),
            stiffness=frozen(stiffness),
            rest_length=frozen(rest_length),
            fixed=frozen(fixed),
            gravity=frozen(gravity),
            damping=damping,
            anchor_motion=anchor_motion,
            default_dt=default_dt,
            default_duration=duration,
            description=str(data.get("description", "")),
        )

    def required(self, spec: Mapping[str, Any], key: str, parent: str) -> Any:
        if key not in spec:
            raise self.fail(f"{parent}.{key}", "missing")
        return spec[key]

    def positions(self, particles: Mapping[str, Any], dimension: int
                  ) -> tuple[np.ndarray, tuple[int, ...] | None]:
        """Particle positions, and the lattice counts when a lattice generated them."""
        has_lattice = "lattice" in particles
        has_positions = "positions" in particles
        if has_lattice == has_positions:
            raise self.fail("particles", "give exactly one of 'positions' or 'lattice'")
        if has_positions:
            raw = particles["positions"]
            if not isinstance(raw, (list, tuple)) or not raw:
                raise self.fail("particles.positions", "must be a non-empty list of points")
            pos = np.array([self.vector3(p, f"particles.positions[{i}]")
                            for i, p in enumerate(raw)])
            return pos, None
        lat = self.mapping(particles["lattice"], "particles.lattice")
        counts = lat.get("counts")
        if (not isinstance(counts, (list, tuple)) or len(counts) != dimension
                or not all(isinstance(c, int) and not isinstance(c, bool) and c >= 1
                           for c in counts)):
            raise self.fail("particles.lattice.counts",
                            f"must be {dimension} positive integers, got {counts!r}")
        spacing = lat.get("spacing", 1.0)
        if isinstance(spacing, (list, tuple)):
            sp = [self.number(s, f"particles.lattice.spacing[{i}]", positive=True)
                  for i, s in enumerate(spacing)]
            if len(sp) != dimension:
                raise self.fail("particles.lattice.spacing",
                                f"must have {dimension} values, got {len(sp)}")
        else:
            sp = [self.number(spacing, "particles.lattice.spacing", positive=True)] * dimension
        origin = self.vector3(lat.get("origin", [0.0, 0.0, 0.0]), "particles.lattice.origin")
        grids = np.meshgrid(*[np.arange(c) * s for c, s in zip(counts, sp)], indexing="ij")
        # Scene order: x fastest, then y, then z (row by row).
        coords = [g.transpose().ravel() for g in grids]
        pos = np.zeros((coords[0].size, 3))
        for axis, c in enumerate(coords):
            pos[:, axis] = c
        return pos + origin, tuple(int(c) for c in counts)

    def pairs(self, springs: Mapping[str, Any], n: int,
              lattice: tuple[int, ...] | None) -> np.ndarray:
        has_pairs = "pairs" in springs
        has_connect = "connect" in springs
        if has_pairs == has_connect:
            raise self.fail("springs", "give exactly one of 'pairs' or 'connect'")
        if has_connect:
            if lattice is None:
                raise self.fail("springs.connect", "needs particles.lattice")
            kinds = springs["connect"]
            if isinstance(kinds, str):
                kinds = [kinds]
            allowed = ("edges", "diagonals", "body_diagonals")
            for i, kind in enumerate(kinds):
                if kind not in allowed:
                    raise self.fail(f"springs.connect[{i}]",
                                    f"unknown '{kind}' (one of {', '.join(allowed)})")
            return lattice_springs(lattice, kinds)
        raw = springs["pairs"]
        if not isinstance(raw, (list, tuple)) or not raw:
            raise self.fail("springs.pairs", "must be a non-empty list of [i, j] pairs")
        out = np.empty((len(raw), 2), dtype=np.int64)
        for e, pair in enumerate(raw):
            if (not isinstance(pair, (list, tuple)) or len(pair) != 2
                    or not all(isinstance(v, int) and not isinstance(v, bool) for v in pair)):
                raise self.fail(f"springs.pairs[{e}]", f"must be two integers, got {pair!r}")
            for v in pair:
                if not 0 <= v < n:
                    raise self.fail(f"springs.pairs[{e}]",
                                    f"particle index {v} out of range (0..{n - 1})")
            if pair[0] == pair[1]:
                raise self.fail(f"springs.pairs[{e}]",
                                f"connects particle {pair[0]} to itself")
            out[e] = sorted(pair)
        seen: dict[tuple[int, int], int] = {}
        for e, (i, j) in enumerate(out.tolist()):
            if (i, j) in seen:
                raise self.fail(f"springs.pairs[{e}]",
                                f"duplicate spring {i}-{j} (same as springs.pairs[{seen[i, j]}])")
            seen[i, j] = e
        return out

    def check_springs(self, pairs: np.ndarray, positions: np.ndarray) -> np.ndarray:
        lengths = np.linalg.norm(positions[pairs[:, 1]] - positions[pairs[:, 0]], axis=1)
        scale = float(np.max(lengths)) if lengths.size else 1.0
        short = np.flatnonzero(lengths <= 1e-12 * max(scale, 1e-300))
        if short.size:
            e = int(short[0])
            i, j = pairs[e]
            raise self.fail(f"springs.pairs[{e}]",
                            f"zero-length spring: particles {i} and {j} are at the same position")
        return lengths

    def fixed(self, spec: Any, positions: np.ndarray) -> np.ndarray:
        n = positions.shape[0]
        if spec is None:
            raise self.fail("fixed", "missing: at least one particle must be fixed, otherwise "
                            "the stiffness has rigid-body zero modes")
        spec = self.mapping(spec, "fixed")
        fixed = np.zeros(n, dtype=bool)
        if "indices" in spec:
            idx = spec["indices"]
            if not isinstance(idx, (list, tuple)):
                raise self.fail("fixed.indices", "must be a list of particle indices")
            for k, v in enumerate(idx):
                if not isinstance(v, int) or isinstance(v, bool) or not 0 <= v < n:
                    raise self.fail(f"fixed.indices[{k}]",
                                    f"particle index {v!r} out of range (0..{n - 1})")
                fixed[v] = True
        if "face" in spec:
            face = spec["face"]
            if not isinstance(face, str) or len(face) != 2 or face[0] not in "+-" \
                    or face[1] not in _AXES:
                raise self.fail("fixed.face", f"must be one of +x -x +y -y +z -z, got {face!r}")
            coord = positions[:, _AXES[face[1]]]
            edge = coord.max() if face[0] == "+" else coord.min()
            tol = 1e-9 * max(1.0, float(np.ptp(positions)))
            fixed |= np.abs(coord - edge) <= tol
        unknown = sorted(set(spec) - {"indices", "face"})
        if unknown:
            raise self.fail(f"fixed.{unknown[0]}", "unknown key (use 'indices' or 'face')")
        if not fixed.any():
            raise self.fail("fixed", "no particle is fixed: at least one must be, otherwise the "
                            "stiffness has rigid-body zero modes")
        if fixed.all():
            raise self.fail("fixed", "every particle is fixed: nothing can move")
        return fixed

    def check_connected(self, pairs: np.ndarray, n: int) -> None:
        degree = np.bincount(pairs.ravel(), minlength=n)
        lonely = np.flatnonzero(degree == 0)
        if lonely.size:
            listed = ", ".join(str(i) for i in lonely[:10]) + (" ..." if lonely.size > 10 else "")
            raise self.fail("springs", f"{lonely.size} particle(s) no spring reaches: {listed}")

    def damping(self, spec: Any) -> Damping:
        spec = self.mapping(spec or {}, "damping")
        unknown = sorted(set(spec) - {"ratio", "rayleigh"})
        if unknown:
            raise self.fail(f"damping.{unknown[0]}", "unknown key (use 'ratio' or 'rayleigh')")
        ratio = self.number(spec.get("ratio", 0.0), "damping.ratio", non_negative=True)
        ray = self.mapping(spec.get("rayleigh", {}) or {}, "damping.rayleigh")
        alpha = self.number(ray.get("alpha", 0.0), "damping.rayleigh.alpha", non_negative=True)
        beta = self.number(ray.get("beta", 0.0), "damping.rayleigh.beta", non_negative=True)
        return Damping(ratio, alpha, beta)

    def anchor_motion(self, spec: Any, axes: tuple[int, ...]) -> AnchorMotion:
        if spec is None:
            return AnchorMotion(())
        if not isinstance(spec, (list, tuple)):
            raise self.fail("anchor_motion", "must be a list of sine components")
        comps = []
        for k, item in enumerate(spec):
            field = f"anchor_motion[{k}]"
            item = self.mapping(item, field)
            axis = item.get("axis")
            if axis not in _AXES or _AXES[axis] not in axes:
                raise self.fail(f"{field}.axis", f"must be one of "
                                f"{', '.join('xyz'[a] for a in axes)}, got {axis!r}")
            comps.append(SineComponent(
                axis=_AXES[axis],
                amplitude=self.number(item.get("amplitude"), f"{field}.amplitude"),
                frequency_hz=self.number(item.get("frequency_hz"), f"{field}.frequency_hz",
                                         non_negative=True),
                phase=self.number(item.get("phase", 0.0), f"{field}.phase"),
                ramp_s=self.number(item.get("ramp_s", 0.0), f"{field}.ramp_s",
                                   non_negative=True),
            ))
        return AnchorMotion(tuple(comps))


# --------------------------------------------------------------------------------------------
# Lattices


def lattice_springs(counts: tuple[int, ...], kinds) -> np.ndarray:
    """Spring pairs of a regular lattice with ``counts`` particles per axis (x fastest).

    ``kinds``: any of ``edges`` (axis neighbours), ``diagonals`` (both diagonals of every
    face cell) and ``body_diagonals`` (the four diagonals of every 3D cell).
    """
    dims = len(counts)
    index = np.arange(int(np.prod(counts))).reshape(tuple(reversed(counts)))  # [z][y][x]
    index = index.transpose(tuple(reversed(range(dims))))  # [x][y][z]
    offsets: list[tuple[int, ...]] = []
    for kind in kinds:
        for off in itertools.product((-1, 0, 1), repeat=dims):
            nz = sum(1 for o in off if o != 0)
            if kind == "edges" and nz == 1 and max(off) == 1:
                offsets.append(off)
            elif kind == "diagonals" and nz == 2:
                # one representative of each +/- pair: first non-zero component positive
                if next(o for o in off if o != 0) == 1:
                    offsets.append(off)
            elif kind == "body_diagonals" and nz == 3 and off[0] == 1:
                offsets.append(off)
    pairs = []
    for off in dict.fromkeys(offsets):
        src = tuple(slice(max(0, -o), c - max(0, o)) for o, c in zip(off, counts))
        dst = tuple(slice(max(0, o), c - max(0, -o)) for o, c in zip(off, counts))
        a = index[src].ravel()
        b = index[dst].ravel()
        pairs.append(np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1))
    out = np.concatenate(pairs) if pairs else np.empty((0, 2), dtype=np.int64)
    out = out[np.lexsort((out[:, 1], out[:, 0]))]
    return out.astype(np.int64)


def _lattice_triangles(scene: Scene) -> np.ndarray:
    """Two triangles per square cell of a planar lattice whose four edges are springs."""
    if scene.dimension != 2:
        return np.empty((0, 3), dtype=np.int64)
    pos = scene.rest_positions
    xs = np.unique(np.round(pos[:, 0], 12))
    ys = np.unique(np.round(pos[:, 1], 12))
    if xs.size * ys.size != scene.n_particles or xs.size < 2 or ys.size < 2:
        return np.empty((0, 3), dtype=np.int64)
    ix = np.searchsorted(xs, np.round(pos[:, 0], 12))
    iy = np.searchsorted(ys, np.round(pos[:, 1], 12))
    grid = np.full((ys.size, xs.size), -1, dtype=np.int64)
    grid[iy, ix] = np.arange(scene.n_particles)
    a = grid[:-1, :-1].ravel()
    b = grid[:-1, 1:].ravel()
    c = grid[1:, 1:].ravel()
    d = grid[1:, :-1].ravel()
    edges = {tuple(p) for p in scene.springs.tolist()}

    def has(u, v):
        return np.array([(min(p, q), max(p, q)) in edges for p, q in zip(u, v)], dtype=bool)

    cell = has(a, b) & has(b, c) & has(c, d) & has(d, a)
    tris = np.concatenate([np.stack([a, b, c], 1)[cell], np.stack([a, c, d], 1)[cell]])
    return tris
