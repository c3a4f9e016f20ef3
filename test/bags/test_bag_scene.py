"""A run's bag keeps its scene as an attached archive of arrays; older bags' YAML still reads."""
from __future__ import annotations

from mcap.reader import make_reader
from mcap.records import SummaryOffset
from mcap.stream_reader import StreamReader
from modal_spring_ros.bags.files.capture import RunBagWriter
from modal_spring_ros.bags.files.reader import BagReader
from modal_spring_ros.bags.files.writer import BagError, BagWriter, SCENE_ATTACHMENT
from modal_spring_ros.core.model.scene import SceneError
from modal_spring_ros.scenes.files.scene_archive import MEDIA_TYPE
from modal_spring_ros.scenes.files.writing import scene_to_yaml
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest


def capture(path, scene, frames: int = 3) -> None:
    bag = RunBagWriter(path, scene, None, dt=1e-3, frame_every=0, duration=0.0,
                       parameters={'scene': scene.name}, node='/modal_spring')
    for k in range(frames):
        bag.frame(1e-3 * k, scene.rest_positions)
    bag.close()


def assert_same(scene, again) -> None:
    for field in ('rest_positions', 'mass', 'springs', 'stiffness', 'fixed', 'triangles'):
        np.testing.assert_array_equal(getattr(again, field), getattr(scene, field), field)


def test_a_capture_attaches_its_scene_and_every_summary_group_holds_records(tmp_path):
    scene = load_scene('soft_block_3d')        # a volume with its skin's triangles
    capture(tmp_path / 'run', scene)
    bag = BagReader(tmp_path / 'run')
    assert bag.finalised and bag.run_record()['scene_archive'] == SCENE_ATTACHMENT
    assert_same(scene, bag.scene())
    path = tmp_path / 'run' / 'run_0.mcap'
    with open(path, 'rb') as fh:
        (attachment,) = make_reader(fh).iter_attachments()
    assert (attachment.name, attachment.media_type) == (SCENE_ATTACHMENT, MEDIA_TYPE)
    with open(path, 'rb') as fh:
        offsets = [r for r in StreamReader(fh, skip_magic=False).records
                   if isinstance(r, SummaryOffset)]
    assert offsets and all(o.group_length > 0 for o in offsets), offsets


def test_a_bag_cut_short_still_gives_its_scene(tmp_path):
    scene = load_scene('sheet_10x10')
    capture(tmp_path / 'run', scene, frames=2000)    # a few chunks
    path = tmp_path / 'run' / 'run_0.mcap'
    data = path.read_bytes()
    (tmp_path / 'cut').mkdir()
    (tmp_path / 'cut' / 'cut_0.mcap').write_bytes(data[:len(data) * 3 // 4])   # no summary
    bag = BagReader(tmp_path / 'cut')
    assert not bag.finalised
    assert_same(scene, bag.scene())


def test_a_bag_written_before_scenes_were_archived_reads_its_yaml(tmp_path):
    scene = load_scene('sheet_10x10')
    with BagWriter(tmp_path / 'old') as writer:
        writer.add_topic('/points', 'sensor_msgs/msg/PointCloud2', '')
        writer.add_run_record({'source': 'modal_spring_sim', 'scene_yaml': scene_to_yaml(scene)})
    assert_same(scene, BagReader(tmp_path / 'old').scene())


def test_a_missing_or_damaged_scene_is_named(tmp_path):
    with BagWriter(tmp_path / 'none') as writer:
        writer.add_topic('/points', 'sensor_msgs/msg/PointCloud2', '')
        writer.add_run_record({'source': 'elsewhere'})
    assert BagReader(tmp_path / 'none').scene() is None
    with BagWriter(tmp_path / 'missing') as writer:
        writer.add_topic('/points', 'sensor_msgs/msg/PointCloud2', '')
        writer.add_run_record({'scene_archive': SCENE_ATTACHMENT})
    with pytest.raises(BagError, match="the run record's scene 'scene.npz' is not attached"):
        BagReader(tmp_path / 'missing').scene()
    with BagWriter(tmp_path / 'damaged', attachments=True) as writer:
        writer.add_topic('/points', 'sensor_msgs/msg/PointCloud2', '')
        writer._writer.add_attachment(0, 0, SCENE_ATTACHMENT, MEDIA_TYPE, b'PK\x03\x04 cut')
        writer.add_run_record({'scene_archive': SCENE_ATTACHMENT})
    with pytest.raises(SceneError, match=r'damaged \(scene\): not a readable scene archive'):
        BagReader(tmp_path / 'damaged').scene()


def test_a_scene_needs_a_writer_made_for_attachments_and_nothing_is_written(tmp_path):
    with BagWriter(tmp_path / 'plain') as writer:
        with pytest.raises(BagError, match='a scene needs a writer made with attachments'):
            writer.add_run_record({'source': 'x'}, load_scene('sheet_10x10'))
    assert BagReader(tmp_path / 'plain').run_record() == {}
