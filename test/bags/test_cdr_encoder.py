"""CDR encoding from ``.msg`` definitions: by hand on a small type, round trips on real ones."""
from __future__ import annotations

import array
import struct

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import (Point, PointStamped, PoseStamped, TransformStamped,
                               WrenchStamped)
from modal_spring_ros.bags.messages.cdr_encoder import definitions, EncodingError, message_encoder
from modal_spring_ros.bags.messages.message_definitions import full_definition
import numpy as np
import pytest
from rcl_interfaces.msg import Parameter, ParameterEvent, ParameterValue
from rclpy.serialization import deserialize_message
from rosbags.typesys import get_typestore, Stores
from sensor_msgs.msg import PointCloud2, PointField, TimeReference
from std_msgs.msg import ColorRGBA
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import Marker

SMALL = """# a comment line
uint8 KIND_A=1      # a constant: no bytes
uint8 a
float64 b 0.5       # a default value
string s
int16[] v
uint32[2] f
Inner[<=3] inner
================================================================================
MSG: test/Inner
bool flag
"""


def test_a_small_type_is_encoded_byte_for_byte_as_cdr_lays_it_out():
    message = {'a': 7, 'b': 2.5, 's': 'hi', 'v': [-1, 2, 3], 'f': np.array([9, 10]),
               'inner': [{'flag': True}, {'flag': False}]}
    expected = (b'\x00\x01\x00\x00'                    # little-endian plain CDR
                + b'\x07' + bytes(7)                    # a, then padding to b's 8
                + struct.pack('<d', 2.5)                # b at 8
                + struct.pack('<I', 3) + b'hi\x00'      # s: its length with the zero, at 16
                + bytes(1) + struct.pack('<I', 3)       # padding to 24: v's count
                + struct.pack('<3h', -1, 2, 3)          # v's items at 28
                + bytes(2) + struct.pack('<2I', 9, 10)  # f at 36: a fixed array, no count
                + struct.pack('<I', 2) + b'\x01\x00')   # inner: a bounded sequence of two
    assert message_encoder('test/msg/Small', SMALL)(message) == expected
    fields = definitions('test/msg/Small', SMALL)
    assert [f.name for f in fields['test/Small']] == ['a', 'b', 's', 'v', 'f', 'inner']
    assert fields['test/Small'][5].item == 'test/Inner'


def test_messages_that_do_not_fit_their_definition_are_refused_by_name():
    encode = message_encoder('test/msg/Small', SMALL)
    good = {'a': 0, 'b': 0.0, 's': '', 'v': [], 'f': [1, 2], 'inner': []}
    with pytest.raises(EncodingError, match=r'test/Small\.f: 3 items where the definition '
                                            r'fixes 2'):
        encode({**good, 'f': [1, 2, 3]})
    with pytest.raises(EncodingError, match=r'test/Small\.inner: 4 items, more than its bound 3'):
        encode({**good, 'inner': [{'flag': True}] * 4})
    with pytest.raises(EncodingError, match='no definition of test/Inner'):
        message_encoder('test/msg/Small', SMALL.split('=' * 80)[0])
    with pytest.raises(EncodingError, match='cannot read the field type'):
        message_encoder('test/msg/Bad', 'int32[x] broken\n')
    assert message_encoder('test/msg/Empty', '# nothing\n')({}) == b'\x00\x01\x00\x00\x00'


def _cloud() -> PointCloud2:
    cloud = PointCloud2(height=1, width=3, is_bigendian=False, point_step=12, row_step=36,
                        is_dense=True, data=array.array('B', range(36)))
    cloud.fields = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                    for i, n in enumerate('xyz')]
    cloud.header.frame_id, cloud.header.stamp.sec = 'world', 12
    return cloud


def _messages():
    event = ParameterEvent(node='/modal_spring', changed_parameters=[Parameter(
        name='filter.gains', value=ParameterValue(
            type=8, double_array_value=[1.0, 0.5], string_array_value=['a', 'bc'],
            byte_array_value=[b'\x01', b'\xff'], bool_array_value=[True, False],
            integer_array_value=[-3, 4]))])
    pose = PoseStamped()
    pose.pose.position.x, pose.pose.orientation.w = 0.25, 1.0
    wrench = WrenchStamped()
    wrench.wrench.force.z = -2.0
    marker = Marker(ns='colliders', id=3, type=Marker.SPHERE, text='touch',
                    points=[Point(x=1.0), Point(y=2.0)], colors=[ColorRGBA(r=1.0, a=0.5)])
    marker.lifetime.nanosec = 5
    status = DiagnosticStatus(level=DiagnosticStatus.WARN, name='modal_spring', message='m',
                              values=[KeyValue(key='k', value='v')])
    return [('sensor_msgs/msg/PointCloud2', _cloud()),
            ('rcl_interfaces/msg/ParameterEvent', event),
            ('geometry_msgs/msg/PoseStamped', pose),
            ('geometry_msgs/msg/WrenchStamped', wrench),
            ('geometry_msgs/msg/PointStamped', PointStamped(point=Point(x=0.1, y=0.2))),
            ('tf2_msgs/msg/TFMessage', TFMessage(transforms=[TransformStamped(
                child_frame_id='modal_spring_object')])),
            ('sensor_msgs/msg/TimeReference', TimeReference(source='modal_spring')),
            ('visualization_msgs/msg/Marker', marker),
            ('diagnostic_msgs/msg/DiagnosticArray', DiagnosticArray(status=[status]))]


@pytest.mark.parametrize('type_name, message', _messages(),
                         ids=[name for name, _ in _messages()])
def test_real_messages_read_back_by_rclpy_and_by_rosbags_strict_reader(type_name, message):
    """The rclpy reader gives the message back; rosbags' refuses a byte too many or too few."""
    data = message_encoder(type_name, full_definition(type_name))(message)
    assert deserialize_message(data, type(message)) == message
    store = get_typestore(Stores.ROS2_JAZZY)
    decoded = store.deserialize_cdr(data, type_name)
    assert store.serialize_cdr(decoded, type_name).tobytes() == data   # the same bytes
