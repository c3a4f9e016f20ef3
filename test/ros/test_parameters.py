"""The node's parameters describe a run: each maps onto the configuration, errors name it."""
from __future__ import annotations

from modal_spring_ros.core.config import ConfigError
from modal_spring_ros.ros.parameters import broadcast_frames, config_from_parameters, PARAMETERS
import pytest

DEFAULTS = {name: default for name, (default, _) in PARAMETERS.items()}


def test_the_horizon_of_the_automatic_choice_is_the_scene_s_unless_set():
    assert config_from_parameters(DEFAULTS).horizon_s is None      # the scene's duration
    config = config_from_parameters({**DEFAULTS, 'modal.horizon': 30.0})
    assert config.horizon_s == 30.0


def test_a_horizon_beyond_a_day_is_refused_by_its_name():
    with pytest.raises(ConfigError, match=r'^modal\.horizon \(1000000.0\) must be a number of'):
        config_from_parameters({**DEFAULTS, 'modal.horizon': 1e6})


@pytest.mark.parametrize('values,reason', [
    ({'anchor.source': 'tf'}, 'needs anchor.frame'),
    ({'anchor.source': 'tf', 'anchor.frame': '/world'}, 'is frame_id'),
    ({'tf.object_frame': '/world'}, 'a frame cannot be its own parent'),
    ({'tf.clamp_frame': 'world'}, 'a frame cannot be its own parent'),
    ({'tf.clamp_frame': 'modal_spring_object'}, 'are both'),
])
def test_bad_tf_frames_are_refused_by_name(values, reason):
    with pytest.raises(ValueError, match=reason):
        config_from_parameters({**DEFAULTS, **values})


@pytest.mark.parametrize('namespace, frames', [
    ('/', ('modal_spring_object', 'modal_spring_clamp')),
    ('/left', ('left/modal_spring_object', 'left/modal_spring_clamp')),
    ('/cell_2/right/', ('cell_2/right/modal_spring_object', 'cell_2/right/modal_spring_clamp'))])
def test_the_broadcast_frames_are_the_node_s_own_under_its_namespace(namespace, frames):
    assert broadcast_frames(DEFAULTS, namespace) == frames
    # a name given is used as given, in any namespace (without tf2's unwanted leading slash)
    given = {**DEFAULTS, 'tf.object_frame': '/sheet', 'tf.clamp_frame': 'tool0_grip'}
    assert broadcast_frames(given, namespace) == ('sheet', 'tool0_grip')


def test_tf_frames_pass_when_following_a_frame_or_not_broadcasting():
    config_from_parameters({**DEFAULTS, 'anchor.source': 'tf', 'anchor.frame': 'gripper'})
    config_from_parameters({**DEFAULTS, 'tf.publish': False, 'tf.object_frame': ''})


def test_the_filter_s_shape_comes_from_its_parameters():
    band = config_from_parameters({
        **DEFAULTS, 'filter.type': 'lowpass', 'filter.high_hz': 9.0, 'filter.order': 4,
        'filter.gains': '1:2:6, peak:5:1:-3  low_shelf:2:4', 'filter.gains_act_on': 'load',
        'filter.damping': '0:3:0.1'}).band
    assert (band.order, band.acts_on) == (4, 'load')
    assert band.gains == ('1:2:6', 'peak:5:1:-3', 'low_shelf:2:4')
    assert band.damping == ('0:3:0.1',)


@pytest.mark.parametrize('values,reason', [
    ({'filter.gains': '5:2:6'}, r"^filter\.gains: '5:2:6': LOW \(5 Hz\) must be at least 0"),
    ({'filter.order': 3, 'filter.by': 'index'},
     r"^filter\.order \(3\) rounds edges in Hz: it needs filter\.by 'hz'"),
    ({'filter.order': 2, 'filter.type': 'highpass'},
     r'^filter\.low_hz must be above 0 Hz for a rounded highpass edge'),
    ({'filter.damping': '0:3:2'}, r"^filter\.damping: damping '0:3:2': RATIO \(2\)"),
    ({'filter.gains_act_on': 'input'}, r"^filter\.gains_act_on 'input' must be one of"),
    ({'filter.gains': '1:2:6', 'method': 'full'},
     r'^a filter shape \(filter\.order, filter\.gains, filter\.damping\) acts on modes'),
    ({'filter.damping': '0:3:0.1', 'modal.auto': True}, r'^modal\.auto chooses modes'),
])
def test_an_impossible_filter_shape_is_refused_by_its_name(values, reason):
    with pytest.raises(ValueError, match=reason):
        config_from_parameters({**DEFAULTS, **values})
