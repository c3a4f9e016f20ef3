"""
The TF listener: tf2's own buffer where ``tf2_ros`` imports, the project's tree where it does not.

``tf2_ros`` is not among the ROS wheels on PyPI, so its path is checked against a stand-in with
tf2's interface (``Buffer.set_transform``, ``set_transform_static``, ``lookup_transform``,
``TransformException``) that knows only direct links: what the listener hands it, in which
call, and that its answers (and its refusals) are the ones the listener gives.
"""
from __future__ import annotations

import math
import types

from modal_spring_ros.ros.frames.frame_tree import Transform
from modal_spring_ros.ros.frames.tf import TfListener, transform_message
import numpy as np
import pytest
from tf2_msgs.msg import TFMessage


class _TransformException(Exception):
    pass


class _Buffer:
    """tf2_ros.Buffer's interface, over direct links only."""

    def __init__(self):
        self.links, self.static, self.authorities = {}, set(), set()

    def set_transform(self, transform, authority):
        self.links[(transform.header.frame_id, transform.child_frame_id)] = transform
        self.authorities.add(authority)

    def set_transform_static(self, transform, authority):
        self.set_transform(transform, authority)
        self.static.add((transform.header.frame_id, transform.child_frame_id))

    def lookup_transform(self, target, source, time):
        assert time.nanoseconds == 0                       # the latest, as tf2 takes Time()
        try:
            return self.links[(target, source)]
        except KeyError:
            raise _TransformException(f'"{source}" passed to lookupTransform argument '
                                      'source_frame does not exist') from None


def _stand_in():
    return types.SimpleNamespace(Buffer=_Buffer, TransformException=_TransformException)


class _Node:
    """A node's subscriptions, by topic."""

    def __init__(self):
        self.callbacks = {}

    def create_subscription(self, message_type, topic, callback, qos):
        assert message_type is TFMessage
        self.callbacks[topic] = callback


def _link(parent, child, x, stamp=None):
    return transform_message(parent, child, Transform(np.array([x, 0.0, 0.0]),
                                                      np.array([0.0, 0.0, 0.0, 1.0])), stamp)


@pytest.fixture
def heard():
    node, updates = _Node(), []
    listener = TfListener(node, lambda: updates.append(1), tf2=_stand_in())
    return node, listener, updates


def test_where_tf2_imports_its_buffer_holds_the_transforms_and_answers(heard):
    node, listener, updates = heard
    node.callbacks['/tf'](TFMessage(transforms=[_link('world', 'base', 1.0),
                                                _link('base', 'tool', 0.5)]))
    node.callbacks['/tf_static'](TFMessage(transforms=[_link('world', 'table', 2.0)]))
    assert updates == [1, 1]
    buffer = listener.buffer
    assert set(buffer.links) == {('world', 'base'), ('base', 'tool'), ('world', 'table')}
    assert buffer.static == {('world', 'table')}
    assert buffer.authorities == {TfListener.AUTHORITY}
    found = listener.lookup('base', 'tool')
    np.testing.assert_allclose(found.translation, [0.5, 0.0, 0.0])
    # tf2 answers, not the tree: this stand-in composes nothing, the tree would
    assert isinstance(listener.tree.lookup('world', 'tool'), Transform)
    why = listener.lookup('world', 'tool')
    assert why.startswith('tf2 cannot carry tool into world: "tool" passed to lookupTransform')


def test_a_transform_the_tree_refuses_never_reaches_tf2(heard):
    node, listener, _ = heard
    bad = _link('world', 'base', math.nan)
    node.callbacks['/tf'](TFMessage(transforms=[bad, _link('world', 'arm', 1.0)]))
    assert listener.refused == 1 and 'non-finite' in listener.last_refusal
    assert set(listener.buffer.links) == {('world', 'arm')}


def test_without_tf2_the_projects_tree_answers():
    node = _Node()
    listener = TfListener(node, tf2=None)
    assert listener.buffer is None
    node.callbacks['/tf'](TFMessage(transforms=[_link('world', 'base', 1.0),
                                                _link('base', 'tool', 0.5)]))
    found = listener.lookup('world', 'tool')
    np.testing.assert_allclose(found.translation, [1.5, 0.0, 0.0])
    assert listener.lookup('world', 'nowhere') == "frame 'nowhere' is not in the TF tree"
