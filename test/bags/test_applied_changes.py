"""The changes a node applied, read back in the simulation time they took effect at."""
from __future__ import annotations

from modal_spring_ros.bags.files.applied_changes import applied_changes, parameter_event
from modal_spring_ros.bags.files.reader import BagReader
from modal_spring_ros.bags.files.writer import BagError, BagWriter
import pytest
from std_msgs.msg import String


def _bag(path, events, type_name='rcl_interfaces/msg/ParameterEvent'):
    with BagWriter(path) as writer:
        writer.add_topic('/ns/applied_parameter_events', type_name)
        for log_ns, message in events:
            writer.write_message('/ns/applied_parameter_events', message, log_ns)
    return BagReader(path)


def test_each_change_is_read_at_its_simulation_time_for_its_node_only(tmp_path):
    bag = _bag(tmp_path / 'b', [
        (5, parameter_event(12.25, '/ns/sim', {'filter.type': 'lowpass',
                                               'filter.high_hz': 12.0})),
        (6, parameter_event(3.0, '/ns/other', {'filter.high_hz': 1.0})),
        (9, parameter_event(12.5, '/ns/sim', {'modal.modes': 24}))])
    assert applied_changes(bag, '/ns/points', '/ns/sim') == [
        (12_250_000_000, {'filter.type': 'lowpass', 'filter.high_hz': 12.0}),
        (12_500_000_000, {'modal.modes': 24})]
    assert applied_changes(bag, '/points', '/ns/sim') is None     # not beside that cloud


def test_a_topic_of_another_type_is_refused_by_name(tmp_path):
    bag = _bag(tmp_path / 'b', [(1, String(data='x'))], type_name='std_msgs/msg/String')
    with pytest.raises(BagError, match='/ns/applied_parameter_events is std_msgs/msg/String, '
                                       'not rcl_interfaces/msg/ParameterEvent'):
        applied_changes(bag, '/ns/points', '/ns/sim')
