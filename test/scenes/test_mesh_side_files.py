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
import subprocess
import sys

from modal_spring_ros.core.model.scene import SceneError
from modal_spring_ros.scenes.meshes import mesh_files
from modal_spring_ros.scenes.meshes.mesh_files import read_mesh
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
