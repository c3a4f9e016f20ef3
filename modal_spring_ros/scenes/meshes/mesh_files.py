"""
Mesh files read into vertices and cells: surfaces (OBJ, STL, PLY, glTF/GLB) and tetrahedra.

Surfaces are read with trimesh, tetrahedral volume meshes (Gmsh ``.msh``, VTK ``.vtk``/``.vtu``)
with meshio: both well kept, MIT-licensed and pure Python over numpy, and between them the formats
a robot's assets come in (a URDF's visual meshes are STL, OBJ or COLLADA exported to glTF; a
volume mesh from Gmsh or TetGen is ``.msh`` or ``.vtk``). Vertices that touch the same point are
merged (an STL lists each triangle's corners on their own), and vertices no cell uses are left
out. ``package://pkg/path`` is resolved through the ament index, as URDF meshes are.

Every problem is a :class:`~modal_spring_ros.core.model.scene.SceneError` naming the file. The
parsers run in an interpreter of their own (:mod:`.mesh_parsing`) under an address-space limit
(at least 1 GiB, or 16 times the file's size, within the memory available): a decompression
bomb or a file that claims huge sizes fails there in one line instead of taking the machine,
and Ctrl-C ends it at any point of the read. Its CPU time is bounded too (a minute, and two
seconds more per MiB of the file): a file that sends a parser into a loop is refused, never
waited for.
"""
from __future__ import annotations

import dataclasses
import io
import math
import os
from pathlib import Path
import signal
import stat
import subprocess
import sys

from modal_spring_ros.core.model.integer_rows import unique_rows
from modal_spring_ros.core.model.scene import SceneError
from modal_spring_ros.scenes.ament_index import package_share
from modal_spring_ros.scenes.fields.limits import available_memory
import numpy as np

#: formats read as surfaces (trimesh), and as volume meshes (meshio)
SURFACE_SUFFIXES = ('.obj', '.stl', '.ply', '.glb', '.gltf', '.off')
VOLUME_SUFFIXES = ('.msh', '.vtk', '.vtu')
#: largest mesh file read, bytes
MAX_BYTES = 256 * 1024 * 1024
#: vertices closer than this share of the mesh's size are one vertex
MERGE_RTOL = 1e-9
#: the memory parsing a mesh may take (beyond what its interpreter maps before it starts): at
#: least this, or this many times the file's size, within what the machine has available
MIN_PARSE_BYTES = 1 << 30
PARSE_BYTES_PER_FILE_BYTE = 16
#: the CPU time parsing a mesh may take, its interpreter's start included: at least this, s, and
#: this much more per MiB of the file (a 600,000-vertex OBJ of 43 MiB takes 3 s in all)
MIN_PARSE_CPU_S = 60.0
PARSE_CPU_S_PER_MIB = 2.0
#: the module a mesh is parsed in (its own interpreter), and its exit status for a refusal
PARSER = 'modal_spring_ros.scenes.meshes.mesh_parsing'
PARSE_REFUSED = 2


@dataclasses.dataclass(frozen=True)
class MeshData:
    """Vertices (n, 3) and the cells that use them: triangles (T, 3) or tetrahedra (K, 4)."""

    vertices: np.ndarray
    triangles: np.ndarray
    tetrahedra: np.ndarray


def resolve_mesh_path(name: str, scene_source: str) -> Path:
    """
    Return the file a scene's ``mesh.file`` names.

    ``package://pkg/rest`` (the package's share folder), an absolute path, or a path relative
    to the scene file's folder (the working folder for a scene given as text).

    :raises SceneError: an unknown package.
    """
    if name.startswith('package://'):
        package, _, rest = name[len('package://'):].partition('/')
        share = package_share(package)
        if share is None:
            raise SceneError(f"package '{package}' of {name} is not installed (not in the "
                             'ament index)')
        return share / rest
    path = Path(os.path.expanduser(name))
    if path.is_absolute():
        return path
    base = Path(scene_source).parent if Path(scene_source).is_file() else Path.cwd()
    return base / path


def read_mesh(path: Path) -> MeshData:
    """
    Read a mesh file: its vertices, triangles and tetrahedra (either may be empty).

    :raises SceneError: not a regular file, too large, an unknown format, or unreadable.
    """
    suffix = path.suffix.lower()
    if suffix not in SURFACE_SUFFIXES + VOLUME_SUFFIXES:
        raise SceneError(f'{path}: unknown mesh format {suffix or "(none)"} (read: '
                         f"{', '.join(SURFACE_SUFFIXES + VOLUME_SUFFIXES)})")
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise SceneError(f'{path}: cannot read mesh file: {exc.strerror or exc}') from None
    if not path.is_file():
        raise SceneError(f'{path}: cannot read mesh file: not a regular file')
    if size > MAX_BYTES:
        raise SceneError(f'{path}: mesh file of {size / 2**20:.0f} MiB is larger than the '
                         f'{MAX_BYTES / 2**20:.0f} MiB read')
    budget = min(max(MIN_PARSE_BYTES, PARSE_BYTES_PER_FILE_BYTE * size), available_memory())
    cpu_s = MIN_PARSE_CPU_S + PARSE_CPU_S_PER_MIB * size / 2**20
    vertices, triangles, tetrahedra = _parse_in_child(path, budget, cpu_s)
    return _merged(vertices, triangles, tetrahedra)


def _parse_in_child(path: Path, budget: int,
                    cpu_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Run :func:`parse_mesh` in its own interpreter (:mod:`.mesh_parsing`); its arrays."""
    env = dict(os.environ, OPENBLAS_NUM_THREADS='1', OMP_NUM_THREADS='1')
    child = subprocess.Popen([sys.executable, '-m', PARSER, str(path), str(MAX_BYTES),
                              str(budget), str(math.ceil(cpu_s))], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, env=env)
    try:
        out, err = child.communicate()
    finally:                          # Ctrl-C (or any error) here: the child goes too
        if child.poll() is None:
            child.kill()
            child.wait()
    said = err.decode(errors='replace').strip().splitlines()
    if child.returncode == PARSE_REFUSED and said:
        raise SceneError(said[-1])
    if child.returncode == -signal.SIGXCPU:      # its CPU limit (RLIMIT_CPU) reached
        raise SceneError(f'{path}: reading the mesh takes more than the {cpu_s:.0f} s of CPU it '
                         'may take (a damaged or hostile file, or too large a mesh)')
    if child.returncode != 0:
        why = (f'killed by {signal.Signals(-child.returncode).name}' if child.returncode < 0
               else f'exit {child.returncode}: {said[-1] if said else "no message"}')
        raise SceneError(f'{path}: cannot read mesh file: its reader ended ({why})')
    try:
        with np.load(io.BytesIO(out), allow_pickle=False) as arrays:
            return arrays['vertices'], arrays['triangles'], arrays['tetrahedra']
    except (OSError, ValueError, KeyError) as exc:
        raise SceneError(f'{path}: cannot read mesh file: its reader answered nothing '
                         f'readable ({exc})') from None


def parse_mesh(path: Path, max_bytes: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Parse a mesh file into vertices, triangles and tetrahedra (in :mod:`.mesh_parsing`).

    :raises SceneError: the parser's any failure, naming the file.
    """
    try:
        if path.suffix.lower() in VOLUME_SUFFIXES:
            vertices, triangles, tetrahedra = _read_volume(path)
        else:
            vertices, triangles = _read_surface(path, max_bytes)
            tetrahedra = np.empty((0, 4), dtype=np.int64)
    except (SceneError, MemoryError):
        raise
    except Exception as exc:  # noqa: B902 - a parser's any failure is the file's
        raise SceneError(f'{path}: cannot read mesh file: {type(exc).__name__}: '
                         f'{str(exc).splitlines()[0] if str(exc) else "unreadable"}') from None
    if not np.all(np.isfinite(vertices)):
        raise SceneError(f'{path}: mesh has vertices that are not finite numbers')
    return vertices, triangles, tetrahedra


def checked_side_file(folder: Path, name: str, budget: list[int]) -> bytes:
    """
    Return the bytes of a file a mesh refers to (an OBJ's materials, a glTF's buffers).

    Checked as the mesh itself is: a regular file (never a FIFO or a device, which would hang
    the reader), inside the mesh's folder, within what is left of ``budget`` ([bytes], the
    mesh's and its side files' together, taken from as they are read).

    :raises SceneError: any of these.
    """
    root = folder.resolve()
    target = (root / name).resolve()
    if not target.is_relative_to(root):
        raise SceneError(f'{folder / name}: a file the mesh refers to is outside its folder')
    try:
        info = os.stat(target)
    except OSError as exc:
        raise SceneError(f'{folder / name}: cannot read a file the mesh refers to: '
                         f'{exc.strerror or exc}') from None
    if not stat.S_ISREG(info.st_mode):
        raise SceneError(f'{folder / name}: a file the mesh refers to is not a regular file')
    if info.st_size > budget[0]:
        raise SceneError(f'{folder / name}: the mesh and the files it refers to are larger '
                         f'than the {MAX_BYTES / 2**20:.0f} MiB read')
    budget[0] -= info.st_size
    return target.read_bytes()


def _read_surface(path: Path, max_bytes: int) -> tuple[np.ndarray, np.ndarray]:
    # trimesh takes 0.6 s to import: paid by scenes that read a surface, not by every start
    import trimesh  # noqa: I100
    from trimesh.resolvers import FilePathResolver

    data = path.read_bytes()
    budget = [max_bytes - len(data)]

    class CheckedResolver(FilePathResolver):
        """The files the mesh refers to, each checked before it is read."""

        def get(self, name: str) -> bytes:
            return checked_side_file(path.parent, name, budget)

        def namespaced(self, namespace: str) -> 'CheckedResolver':
            return self

    loaded = trimesh.load(file_obj=io.BytesIO(data), file_type=path.suffix.lower()[1:],
                          resolver=CheckedResolver(str(path)), force='mesh', process=False)
    faces = np.asarray(getattr(loaded, 'faces', np.empty((0, 3))), dtype=np.int64)
    vertices = np.asarray(getattr(loaded, 'vertices', np.empty((0, 3))), dtype=float)
    return vertices.reshape(-1, 3), faces.reshape(-1, 3)


def _read_volume(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    # as trimesh: meshio (and the rich it brings) is loaded by the scenes that read a volume
    import meshio  # noqa: I100
    # the format's own reader: meshio.read prints a reader's error and ends the process itself
    readers = {'.msh': meshio.gmsh.read, '.vtk': meshio.vtk.read, '.vtu': meshio.vtu.read}
    try:
        mesh = readers[path.suffix.lower()](str(path))
    except SystemExit as exc:      # a reader that still exits: the file's error, not the end
        raise SceneError(f'{path}: cannot read mesh file (its reader gave up: exit '
                         f'{exc.code})') from None
    vertices = np.asarray(mesh.points, dtype=float)
    if vertices.ndim != 2 or vertices.shape[1] not in (2, 3):
        raise SceneError(f'{path}: mesh points must have 3 coordinates')
    if vertices.shape[1] == 2:
        vertices = np.column_stack([vertices, np.zeros(len(vertices))])
    cells = {'triangle': [], 'tetra': []}
    for block in mesh.cells:
        if block.type in cells:
            cells[block.type].append(np.asarray(block.data, dtype=np.int64))
    tri = np.concatenate(cells['triangle']) if cells['triangle'] else np.empty((0, 3), int)
    tet = np.concatenate(cells['tetra']) if cells['tetra'] else np.empty((0, 4), int)
    return vertices, tri, tet


def _merged(vertices: np.ndarray, triangles: np.ndarray, tetrahedra: np.ndarray) -> MeshData:
    """Merge coincident vertices, drop the unused, renumber the cells (in the file's order)."""
    n = vertices.shape[0]
    for cells in (triangles, tetrahedra):
        if cells.size and (cells.min() < 0 or cells.max() >= n):
            raise SceneError(f'mesh refers to vertex {int(cells.max())} of {n}')
    size = float(np.max(np.ptp(vertices, axis=0))) if n else 0.0
    key = np.round(vertices / max(size * MERGE_RTOL, 1e-300)).astype(np.int64) if n else \
        np.empty((0, 3), dtype=np.int64)
    _, first, inverse = unique_rows(key, return_index=True, return_inverse=True)
    # numbered in the file's order (fixed indices name the file's vertices)
    rank = np.empty(first.size, dtype=np.int64)
    rank[np.argsort(first, kind='stable')] = np.arange(first.size)
    inverse, first = rank[inverse.ravel()], np.sort(first)
    triangles, tetrahedra = inverse[triangles], inverse[tetrahedra]
    used = np.zeros(first.size, dtype=bool)
    used[triangles.ravel()] = True
    used[tetrahedra.ravel()] = True
    number = np.cumsum(used) - 1
    return MeshData(vertices[first][used], number[triangles].reshape(-1, 3),
                    number[tetrahedra].reshape(-1, 4))
