"""
``modal_spring_node --managed`` over DDS: the lifecycle a launch file or Nav2's manager drives.

configure (the scene loaded, the modes computed), activate (frames), deactivate (no frames, the
run's time held), activate again (from the same time), cleanup (the node's topics and services
gone), configure again (its capture beside the first); a refused transition and a configure
that fails say so and change nothing.
"""
from __future__ import annotations

import threading
import time

from lifecycle_msgs.msg import State, Transition
from lifecycle_msgs.srv import ChangeState, GetState
from modal_spring_ros.bags.files.reader import BagReader
import pytest
from ros_harness import (Client, console_script, NodeProcess, SimTimes, stderr_excerpt,
                         wait_for)
from sensor_msgs.msg import PointCloud2
from std_srvs.srv import Trigger

pytestmark = pytest.mark.ros

NODE = '/managed/modal_spring'


def managed(*params: str) -> NodeProcess:
    ros_args = [x for p in params for x in ('-p', p)] + ['-r', '__ns:=/managed']
    return NodeProcess(argv=[console_script('modal_spring_node'), '--managed', '--ros-args',
                             *ros_args])


GOALS = {Transition.TRANSITION_CONFIGURE: State.PRIMARY_STATE_INACTIVE,
         Transition.TRANSITION_ACTIVATE: State.PRIMARY_STATE_ACTIVE,
         Transition.TRANSITION_DEACTIVATE: State.PRIMARY_STATE_INACTIVE,
         Transition.TRANSITION_CLEANUP: State.PRIMARY_STATE_UNCONFIGURED}


def state(client: Client) -> int:
    """Return the node's lifecycle state id (asked again should an answer be lost)."""
    return client.call(GetState, f'{NODE}/get_state', GetState.Request(),
                       timeout=60.0, resend_s=5.0).current_state.id


def change(client: Client, transition: int) -> bool:
    """
    Ask for ``transition``; return whether it succeeded.

    A transition cannot be asked twice, so an answer lost on a busy machine (a new client's
    first request, before the node matched its response reader) is read from the state the
    node settles in instead.
    """
    request = ChangeState.Request(transition=Transition(id=transition))
    try:
        return client.call(ChangeState, f'{NODE}/change_state', request, timeout=30.0).success
    except TimeoutError:
        assert wait_for(lambda: state(client) in GOALS.values(), 60)   # not in a transition
        return state(client) == GOALS[transition]


def test_the_managed_node_streams_only_while_active_and_cleans_up(tmp_path):
    capture = tmp_path / 'capture'
    node = managed('publish_rate_hz:=30.0', f'record.bag:={capture}')
    client = Client('managed_client')
    sim_time = SimTimes().subscribe(client, '/managed/sim_time')
    points = client.collect(PointCloud2, '/managed/points')
    try:
        assert state(client) == State.PRIMARY_STATE_UNCONFIGURED
        # the state machine refuses what the state does not allow, and nothing changes
        assert not change(client, Transition.TRANSITION_ACTIVATE)
        assert state(client) == State.PRIMARY_STATE_UNCONFIGURED
        assert change(client, Transition.TRANSITION_CONFIGURE)
        assert state(client) == State.PRIMARY_STATE_INACTIVE
        time.sleep(1.0)
        assert points == []                                    # configured: no frame yet
        assert change(client, Transition.TRANSITION_ACTIVATE)
        assert wait_for(lambda: len(points) >= 10, 30)
        assert change(client, Transition.TRANSITION_DEACTIVATE)
        time.sleep(0.3)                                        # frames already sent arrive
        held = len(points)
        last = sim_time(points[-1][1])
        time.sleep(1.5)
        assert len(points) == held                             # inactive: no frames
        assert change(client, Transition.TRANSITION_ACTIVATE)
        assert wait_for(lambda: len(points) >= held + 10, 30)
        # the run went on from where it was: its time did not jump over the inactive 1.5 s
        resumed = sim_time(points[held][1])
        assert last < resumed < last + 0.5, (last, resumed)
        assert change(client, Transition.TRANSITION_DEACTIVATE)
        assert change(client, Transition.TRANSITION_CLEANUP)
        assert state(client) == State.PRIMARY_STATE_UNCONFIGURED
        # the node's own services are gone with its run; configured again, they are back
        names = dict(client.node.get_service_names_and_types())
        assert f'{NODE}/reset' not in names and f'{NODE}/change_state' in names
        assert change(client, Transition.TRANSITION_CONFIGURE)
        assert client.call(Trigger, f'{NODE}/reset', Trigger.Request()).success
        assert change(client, Transition.TRANSITION_ACTIVATE)
        count = len(points)
        assert wait_for(lambda: len(points) >= count + 10, 30)
    finally:
        client.close()
        code, _, err = node.interrupt()
    assert code == 0 and 'Traceback' not in err, stderr_excerpt(err)
    # each configuration's capture, whole: the first kept, the second beside it
    first, second = BagReader(capture), BagReader(tmp_path / 'capture_2')
    assert first.finalised and second.finalised
    assert first.topics['/points'].count >= 20 and second.topics['/points'].count >= 10


def test_a_configure_that_fails_says_why_and_stays_unconfigured():
    node = managed('scene:=/nonexistent/scene.yaml')
    client = Client('managed_bad_client')
    try:
        assert not change(client, Transition.TRANSITION_CONFIGURE)
        assert state(client) == State.PRIMARY_STATE_UNCONFIGURED
        assert node.proc.poll() is None                         # still there, to be fixed
    finally:
        client.close()
        code, _, err = node.interrupt()
    assert code == 0 and 'Traceback' not in err, stderr_excerpt(err)
    assert 'configure failed' in err and 'nonexistent' in err, stderr_excerpt(err)


def test_state_queries_are_answered_while_a_long_configure_runs():
    """
    A configure that computes 80 modes of a 10,000-particle sheet (seconds).

    Meanwhile ``get_state`` answers at once, ``configuring``, as rclcpp's nodes answer, and a
    second transition asked during it is refused by the state machine; the configure ends as
    it would have.
    """
    node = managed('scene:=sheet_100x100', 'filter.type:=lowpass', 'filter.by:=index',
                   'filter.high_mode:=80')
    client = Client('managed_slow_client')
    try:
        assert state(client) == State.PRIMARY_STATE_UNCONFIGURED
        configured = {}
        worker = threading.Thread(target=lambda: configured.setdefault(
            'success', change(client, Transition.TRANSITION_CONFIGURE)))
        worker.start()
        answers = []
        while worker.is_alive() and len(answers) < 5:
            asked = time.monotonic()
            current = client.call(GetState, f'{NODE}/get_state', GetState.Request(),
                                  timeout=60.0).current_state.id
            answers.append((current, time.monotonic() - asked))
            time.sleep(0.1)
        configuring = [waited for current, waited in answers
                       if current == State.TRANSITION_STATE_CONFIGURING]
        assert len(configuring) >= 3 and max(configuring) < 2.0, answers
        refused = ChangeState.Request(transition=Transition(id=Transition.TRANSITION_ACTIVATE))
        if worker.is_alive():
            assert not client.call(ChangeState, f'{NODE}/change_state', refused,
                                   timeout=30.0).success
        worker.join(120)
        assert configured == {'success': True}
        assert state(client) == State.PRIMARY_STATE_INACTIVE
    finally:
        client.close()
        code, _, err = node.interrupt()
    assert code == 0 and 'Traceback' not in err, stderr_excerpt(err)


SHUTDOWN_FROM = {
    State.PRIMARY_STATE_UNCONFIGURED: ([], Transition.TRANSITION_UNCONFIGURED_SHUTDOWN),
    State.PRIMARY_STATE_INACTIVE: ([Transition.TRANSITION_CONFIGURE],
                                   Transition.TRANSITION_INACTIVE_SHUTDOWN),
    State.PRIMARY_STATE_ACTIVE: ([Transition.TRANSITION_CONFIGURE, Transition.TRANSITION_ACTIVATE],
                                 Transition.TRANSITION_ACTIVE_SHUTDOWN),
}


@pytest.mark.parametrize('start', sorted(SHUTDOWN_FROM))
def test_shutdown_from_every_primary_state_finalises_and_releases_the_capture(tmp_path, start):
    capture = tmp_path / 'capture'
    node = managed('publish_rate_hz:=30.0', f'record.bag:={capture}')
    client = Client('managed_shutdown_client')
    points = client.collect(PointCloud2, '/managed/points')
    before, shutdown = SHUTDOWN_FROM[start]
    try:
        for transition in before:
            assert change(client, transition)
        assert state(client) == start
        if start == State.PRIMARY_STATE_ACTIVE:
            assert wait_for(lambda: len(points) >= 5, 30)
        assert change(client, shutdown)
        assert state(client) == State.PRIMARY_STATE_FINALIZED
        time.sleep(0.3)
        sent = len(points)
        time.sleep(1.0)
        assert len(points) == sent                             # finalized: no frames
        assert not change(client, Transition.TRANSITION_CONFIGURE)   # nothing after it
    finally:
        client.close()
        code, _, err = node.interrupt()
    assert code == 0 and 'Traceback' not in err, stderr_excerpt(err)
    if start == State.PRIMARY_STATE_UNCONFIGURED:
        assert not capture.exists()                             # never configured: no bag
    else:
        assert BagReader(capture).finalised                     # closed by the shutdown
