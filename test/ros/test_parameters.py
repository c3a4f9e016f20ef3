"""The node's parameters describe a run: each maps onto the configuration, errors name it."""
from __future__ import annotations

from modal_spring_ros.core.config import ConfigError
from modal_spring_ros.ros.parameters import config_from_parameters, PARAMETERS
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
    ({'tf.object_frame': ''}, 'tf.object_frame must not be empty'),
    ({'tf.clamp_frame': 'world'}, 'a frame cannot be its own parent'),
    ({'tf.clamp_frame': 'modal_spring_object'}, 'are both'),
])
def test_bad_tf_frames_are_refused_by_name(values, reason):
    with pytest.raises(ValueError, match=reason):
        config_from_parameters({**DEFAULTS, **values})


def test_tf_frames_pass_when_following_a_frame_or_not_broadcasting():
    config_from_parameters({**DEFAULTS, 'anchor.source': 'tf', 'anchor.frame': 'gripper'})
    config_from_parameters({**DEFAULTS, 'tf.publish': False, 'tf.object_frame': ''})
