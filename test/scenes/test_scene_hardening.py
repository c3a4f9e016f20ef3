"""
Scene files a careless or hostile user could write.

Each is refused at once with one line that names the field, and nothing hangs, exhausts memory or
ends in a traceback.
"""
from __future__ import annotations

import copy
import os
import random
import re

from modal_spring_ros.cli.modal_spring_sim import main
from modal_spring_ros.core.model.scene import Scene, SceneError
from modal_spring_ros.scenes.fields import limits
from modal_spring_ros.scenes.files.yaml_reading import LOADER, MAX_BYTES
from modal_spring_ros.scenes.resources import builtin_scene_dir, builtin_scene_names, load_scene
from modal_spring_ros.scenes.schema import scene_from_dict, scene_from_yaml
import pytest
import yaml

#: A refusal takes milliseconds; a test stuck longer than this is a hang (pytest-timeout fails
#: it), not a slow machine: no refusal's time is asserted.
hangs_fail = pytest.mark.timeout(120)

SHEET = (builtin_scene_dir() / 'sheet_10x10.yaml').read_text()
BOMB = 'a: &a [x, x, x, x, x, x, x, x, x]\n' + ''.join(
    f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join([f'*{chr(97 + i)}'] * 9)}]\n"
    for i in range(9))


def _replace(text: str, old: str, new: str) -> str:
    assert old in text
    return text.replace(old, new, 1)


CASES = {
    'alias bomb': (BOMB, 'aliases expand to more than'),
    'deep nesting': ('[' * 100 + ']' * 100, 'nested deeper than 16 levels'),
    # libyaml refuses 1000 levels itself, before the check
    'very deep nesting': ('[' * 5000 + ']' * 5000, 'nested deeper than 16 levels'
                          if LOADER is yaml.SafeLoader else
                          'invalid YAML at line 1, column 1001: exceeded maximum nesting depth'),
    'syntax error': ('name: [1, 2\nfoo: bar: baz\n', 'invalid YAML at line 2, column 4'),
    'float dimension': (_replace(SHEET, 'dimension: 2', 'dimension: 2.0'),
                        'dimension: must be 1, 2 or 3, got 2.0'),
    'connect a number': (_replace(SHEET, 'connect: [edges, diagonals]', 'connect: 5'),
                         'springs.connect: must be a kind or a list of kinds, got 5'),
    'axis a list': (_replace(_replace(SHEET, 'dimension: 2', 'dimension: 1'), 'plane: xz',
                             'axis: [y]'),
                    "axis: must be one of x, y, z, got ['y']"),
    'anchor axis a list': (_replace(SHEET, '{axis: x,', '{axis: [x],'),
                           "anchor_motion[0].axis: must be one of x, z, got ['x']"),
    'unknown plane': (_replace(SHEET, 'plane: xz', 'plane: xq'),
                      "plane: must be one of xz, xy, yz, got 'xq'"),
    'plane of a 3D scene': (_replace(SHEET, 'dimension: 2', 'dimension: 3'),
                            'plane: only a 2D scene (dimension: 2) has a plane'),
    'shake off the plane': (_replace(SHEET, '{axis: x,', '{axis: y,'),
                            "anchor_motion[0].axis: must be one of x, z, got 'y'"),
    'integer too large': (_replace(SHEET, 'mass: 0.01', 'mass: 1' + '0' * 400),
                          'particles.mass: must be at most 1e+09 in size, got an integer of '
                          '401 digits'),
    'huge lattice': (_replace(SHEET, 'counts: [10, 10]', 'counts: [100000, 100000]'),
                     'particles.lattice.counts: 10,000,000,000 particles need at least'),
    'large lattice': (_replace(SHEET, 'counts: [10, 10]', 'counts: [6000, 6000]'),
                      'particles.lattice.counts: 36,000,000 particles need at least'),
    'tiny step': (_replace(SHEET, 'simulation: {dt: 0.0005', 'simulation: {dt: 1.0e-300'),
                  'simulation.dt: 1e-300 s makes 5e+300 steps'),
    'huge mass': (_replace(SHEET, 'mass: 0.01', 'mass: 1.0e308'),
                  'particles.mass: must be at most 1e+09 in size, got 1e+308'),
    'huge stiffness': (_replace(SHEET, 'stiffness: 1000.0', 'stiffness: 1.0e308'),
                       'springs.stiffness: must be at most 1e+12 in size, got 1e+308'),
    'huge gravity': (_replace(SHEET, 'gravity: [0.0, 0.0, -9.81]', 'gravity: [0, 0, -1.0e308]'),
                     'gravity[2]: must be at most 10000 in size, got -1e+308'),
    'huge amplitude': (_replace(SHEET, 'amplitude: 0.02', 'amplitude: 1.0e308'),
                       'anchor_motion[0].amplitude: must be at most 1000 in size'),
}


@hangs_fail
@pytest.mark.parametrize('name', sorted(CASES))
def test_each_bad_scene_is_one_line_naming_the_field(name, tmp_path, capsys):
    text, message = CASES[name]
    path = tmp_path / 'bad.yaml'
    path.write_text(text)
    with pytest.raises(SystemExit) as info:
        main(['--scene', str(path), '--duration', '0.01', '--quiet'])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and err.startswith('modal_spring_sim: error: '), err
    assert message in err, err
    assert 'Traceback' not in err


@hangs_fail
def test_files_that_are_not_scene_files_are_refused_without_reading_them(tmp_path):
    fifo = tmp_path / 'pipe.yaml'
    os.mkfifo(fifo)                                   # no writer: opening it would block
    big = tmp_path / 'big.yaml'
    with open(big, 'wb') as fh:                       # sparse: costs no disk
        fh.truncate(MAX_BYTES + 1)
    binary = tmp_path / 'binary.yaml'
    binary.write_bytes(b'name: \xff\xfe\n')
    for path, message in ((fifo, 'not a regular file'), ('/dev/zero', 'not a regular file'),
                          (tmp_path, 'a folder'), (big, 'larger than the 16 MiB'),
                          (binary, 'not UTF-8 text (byte 6)')):
        with pytest.raises(SceneError, match=re.escape(message)):
            load_scene(path if isinstance(path, str) else str(path))


MUTATIONS = [-1, 0, 10**400, 2**70, 1e308, float('nan'), float('inf'), 'x', [], {}, None,
             True, [[1]], 2.5, [1, 2, 3, 4], {'a': 1}]


def _mutate(data, rng: random.Random):
    """Return the scene with one value somewhere replaced (or one key removed)."""
    data = copy.deepcopy(data)
    node, path = data, []
    while True:
        keys = list(node.keys()) if isinstance(node, dict) else list(range(len(node)))
        if not keys:
            return data
        key = rng.choice(keys)
        child = node[key]
        if isinstance(child, (dict, list)) and child and rng.random() < 0.7:
            node, path = child, path + [key]
            continue
        if isinstance(node, dict) and rng.random() < 0.15:
            del node[key]
        else:
            node[key] = rng.choice(MUTATIONS)
        return data


@hangs_fail
@pytest.mark.parametrize('name', builtin_scene_names())
def test_random_mutations_of_the_built_in_scenes_load_or_are_refused(name):
    """Every mutation gives a Scene or a SceneError: never another exception, never a hang."""
    source = yaml.safe_load((builtin_scene_dir() / f'{name}.yaml').read_text())
    rng = random.Random(name)
    refused = 0
    for _ in range(60):
        mutated = _mutate(source, rng)
        try:
            assert isinstance(scene_from_dict(mutated, source=name), Scene)
        except SceneError as exc:
            refused += 1
            assert str(exc).startswith(f'{name}: ') and '\n' not in str(exc)
    assert refused > 20                                   # the mutations really are bad


@pytest.mark.parametrize('seed', range(3))
def test_random_bytes_flipped_in_a_scene_file_load_or_are_refused(seed):
    rng = random.Random(seed)
    for _ in range(60):
        raw = bytearray(SHEET.encode())
        for _ in range(rng.randint(1, 5)):
            raw[rng.randrange(len(raw))] = rng.randrange(32, 127)
        try:
            scene_from_yaml(raw.decode(), 'flipped.yaml')
        except SceneError as exc:
            assert '\n' not in str(exc)


def test_numbers_yaml_1_1_reads_as_text_are_numbers():
    """``1e-4`` (no dot) and ``1.0e308`` (no exponent sign) are text to YAML 1.1."""
    scene = scene_from_yaml(SHEET.replace('dt: 0.0005', 'dt: 5e-4'), 'sheet.yaml')
    assert scene.default_dt == 5e-4


def test_available_memory_honours_an_address_space_limit(monkeypatch):
    monkeypatch.setattr(limits.resource, 'getrlimit', lambda _: (2**30, 2**30))
    monkeypatch.setattr(limits, 'mapped_bytes', lambda: 2**29)
    assert 0 < limits.available_memory() <= 2**29
