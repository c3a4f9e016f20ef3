"""
Files a mesh refers to are input too: an OBJ's materials, a glTF's buffers.

Each is checked as the mesh is (a regular file inside the mesh's folder, the whole within the
read's size), so a FIFO named by ``mtllib`` or a glTF buffer hangs nothing, and a small glTF
cannot make the loader read a large neighbour or a file outside its folder.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

from modal_spring_ros.core.model.scene import SceneError
from modal_spring_ros.scenes.meshes import mesh_files
from modal_spring_ros.scenes.meshes.mesh_files import read_mesh
from modal_spring_ros.scenes.resources import executable
import numpy as np
import pytest
import trimesh


def _gltf(folder: Path, uri: str | None = None) -> Path:
    """Write a box as a .gltf with its buffers beside it; its first buffer's URI ``uri``."""
    files = trimesh.exchange.gltf.export_gltf(trimesh.Scene(trimesh.creation.box()))
    model = json.loads(files.pop('model.gltf'))
    for name, data in files.items():
        (folder / name).write_bytes(data)
    if uri is not None:
        model['buffers'][0]['uri'] = uri
    path = folder / 'box.gltf'
    path.write_text(json.dumps(model))
    return path


def test_a_gltf_with_its_buffers_beside_it_reads(tmp_path):
    mesh = read_mesh(_gltf(tmp_path))
    assert len(mesh.vertices) == 8 and len(mesh.triangles) == 12


def test_a_buffer_outside_the_folder_is_refused(tmp_path):
    inner = tmp_path / 'mesh'
    inner.mkdir()
    (tmp_path / 'secret.bin').write_bytes(b'\0' * 144)
    with pytest.raises(SceneError, match='outside its folder'):
        read_mesh(_gltf(inner, '../secret.bin'))


def test_a_large_neighbour_buffer_is_refused_before_it_is_read(tmp_path, monkeypatch):
    monkeypatch.setattr(mesh_files, 'MAX_BYTES', 64 * 1024)
    with open(tmp_path / 'huge.bin', 'wb') as f:      # sparse: no disk used
        f.truncate(2 * 1024 * 1024)
    with pytest.raises(SceneError, match='larger than the'):
        read_mesh(_gltf(tmp_path, 'huge.bin'))


def _read_in_a_process(path: Path) -> subprocess.CompletedProcess:
    code = ('import sys\n'
            'from modal_spring_ros.scenes.meshes.mesh_files import read_mesh\n'
            'from modal_spring_ros.core.model.scene import SceneError\n'
            'try:\n'
            f'    mesh = read_mesh(__import__("pathlib").Path({str(path)!r}))\n'
            '    print("read", len(mesh.vertices))\n'
            'except SceneError as exc:\n'
            '    print("refused:", exc)\n')
    return subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=120)


def test_a_fifo_named_by_a_mesh_hangs_nothing(tmp_path):
    """An OBJ's ``mtllib`` and a glTF's buffer naming a FIFO: read or refused, never waited on."""
    os.mkfifo(tmp_path / 'fifo.mtl')
    os.mkfifo(tmp_path / 'fifo.bin')
    obj = tmp_path / 'tri.obj'
    obj.write_text('mtllib fifo.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n')
    done = _read_in_a_process(obj)                       # the materials are not needed
    assert done.stdout.startswith(('read 3', 'refused:')), done.stderr
    done = _read_in_a_process(_gltf(tmp_path, 'fifo.bin'))
    assert done.stdout.startswith('refused:') and 'not a regular file' in done.stdout, (
        done.stdout + done.stderr)


def _volume_files(folder: Path) -> dict[str, Path]:
    """Write damaged volume meshes: truncated VTK and VTU, an entity-laden VTU, a bad Gmsh."""
    meshio = pytest.importorskip('meshio')
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    mesh = meshio.Mesh(points, [('tetra', np.array([[0, 1, 2, 3]]))])
    mesh.write(folder / 'whole.vtk', binary=True)
    mesh.write(folder / 'whole.vtu', compression='zlib')
    files = {}
    for name in ('whole.vtk', 'whole.vtu'):
        data = (folder / name).read_bytes()
        files[f'truncated {name[-3:]}'] = folder / f'truncated{name[5:]}'
        files[f'truncated {name[-3:]}'].write_bytes(data[:len(data) // 2])
    laughs = ''.join(f'<!ENTITY l{k} "{"&l%d;" % (k - 1) * 10 if k else "ha"}">'
                     for k in range(10))
    files['entity-laden vtu'] = folder / 'laughs.vtu'
    files['entity-laden vtu'].write_text(
        f'<?xml version="1.0"?><!DOCTYPE VTKFile [{laughs}]>'
        '<VTKFile type="UnstructuredGrid"><UnstructuredGrid><Piece NumberOfPoints="1" '
        'NumberOfCells="0"><Points><DataArray>&l9;</DataArray></Points></Piece>'
        '</UnstructuredGrid></VTKFile>')
    files['bad gmsh'] = folder / 'bad.msh'
    files['bad gmsh'].write_text('$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 2 3\n')
    return files


@pytest.mark.parametrize('kind', ['truncated vtk', 'truncated vtu', 'entity-laden vtu',
                                  'bad gmsh'])
def test_a_damaged_volume_mesh_is_one_line_and_exit_2(tmp_path, kind):
    """Read with each format's reader: meshio's ``read`` prints and ends the process itself."""
    path = _volume_files(tmp_path)[kind]
    scene = tmp_path / 'scene.yaml'
    scene.write_text(f'dimension: 3\nmesh: {{file: {path.name}, kind: volume}}\n'
                     'material: {density: 1000.0, stiffness: 100000.0}\n'
                     'fixed: {indices: [0]}\n')
    done = subprocess.run([str(executable('modal_spring_sim')), '--scene', str(scene),
                           '--duration', '0.01', '--quiet'], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 2, done.stdout + done.stderr
    assert done.stderr.count('\n') == 1 and path.name in done.stderr, done.stderr
    assert 'Traceback' not in done.stderr and done.stdout == ''


def test_a_decompression_bomb_is_refused_within_the_parse_s_memory(tmp_path, monkeypatch):
    """A 2 MB ``.vtu`` of zlib blocks that expand to hundreds of MB: one line, nothing taken."""
    meshio = pytest.importorskip('meshio')
    count = 4_000_000
    meshio.Mesh(np.zeros((count, 3)), [('tetra', np.zeros((count // 4, 4), dtype=np.int64))]
                ).write(tmp_path / 'bomb.vtu', compression='zlib')
    assert (tmp_path / 'bomb.vtu').stat().st_size < 4 * 2**20
    monkeypatch.setattr(mesh_files, 'MIN_PARSE_BYTES', 256 * 2**20)
    with pytest.raises(SceneError, match=r'bomb\.vtu: reading the mesh needs more than the 256 '
                                         r'MiB it may take'):
        read_mesh(tmp_path / 'bomb.vtu')


def grid_obj(path: Path, side: int) -> Path:
    """Write a flat ``side`` x ``side`` grid of triangles as an OBJ (large, quick to write)."""
    u, v = np.meshgrid(np.linspace(0, 1, side), np.linspace(0, 1, side))
    vertices = np.column_stack([u.ravel(), np.zeros(u.size), -v.ravel()])
    k = np.arange(side * side).reshape(side, side)[:-1, :-1].ravel()
    faces = np.concatenate([np.column_stack([k, k + 1, k + side]),
                            np.column_stack([k + 1, k + side + 1, k + side])])
    with open(path, 'w') as fh:
        np.savetxt(fh, vertices, fmt='v %.6f %.6f %.6f')
        np.savetxt(fh, faces + 1, fmt='f %d %d %d')
    return path


@pytest.mark.slow
def test_ctrl_c_while_a_large_mesh_is_parsed_ends_the_run_and_its_parser(tmp_path):
    """A 600,000-vertex OBJ takes seconds to parse; Ctrl-C to the group ends both at once."""
    obj = grid_obj(tmp_path / 'big.obj', 775)
    scene = tmp_path / 'scene.yaml'
    scene.write_text('dimension: 3\nmesh: {file: big.obj}\n'
                     'material: {density: 0.2, stiffness: 400.0}\nfixed: {indices: [0]}\n')
    run = subprocess.Popen([str(executable('modal_spring_sim')), '--scene', str(scene),
                            '--duration', '0.01', '--quiet'], stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        parser = []
        end = time.monotonic() + 120
        while not parser and time.monotonic() < end and run.poll() is None:
            time.sleep(0.2)
            parser = _parsers(obj)
        assert parser, 'the mesh was never parsed in its own process'
        os.killpg(run.pid, signal.SIGINT)            # as a terminal's Ctrl-C
        _, err = run.communicate(timeout=30)
    finally:
        if run.poll() is None:
            os.killpg(run.pid, signal.SIGKILL)
            run.wait()
    assert run.returncode in (2, 130) and 'Traceback' not in err, err[-2000:]
    time.sleep(0.5)
    assert _parsers(obj) == []


def _parsers(path: Path) -> list[int]:
    """Return the pids of processes parsing ``path``."""
    found = []
    for entry in Path('/proc').iterdir():
        try:
            command = (entry / 'cmdline').read_bytes().split(b'\0')
        except OSError:
            continue
        if mesh_files.PARSER.encode() in command and str(path).encode() in command:
            found.append(int(entry.name))
    return found


def test_a_parse_beyond_its_cpu_time_is_refused_in_one_line(tmp_path, monkeypatch):
    """
    A parser sent into a loop (here: a parse allowed one second of CPU) ends there, refused.

    A 360,000-vertex OBJ: its interpreter's start, trimesh's import and its parse take about
    two seconds of CPU.
    """
    obj = grid_obj(tmp_path / 'slow.obj', 600)
    monkeypatch.setattr(mesh_files, 'MIN_PARSE_CPU_S', 1.0)
    monkeypatch.setattr(mesh_files, 'PARSE_CPU_S_PER_MIB', 0.0)
    with pytest.raises(SceneError, match=r'slow\.obj: reading the mesh takes more than the 1 s '
                                         r'of CPU it may take'):
        read_mesh(obj)
