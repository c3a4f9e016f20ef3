"""
``modal_spring_node --managed``: the node as a managed (lifecycle) node.

The same node (:class:`~modal_spring_ros.ros.node.ModalSpringNode`) on ``rclpy.lifecycle``'s
state machine, as drivers and Nav2 run theirs: created *unconfigured* with its parameters
declared and nothing else (they can be set freely, and are checked on configure);
``configure`` loads the scene and computes the basis (a bad scene or setting fails the
transition with the reason logged, and the node stays unconfigured); ``activate`` streams;
``deactivate`` stops stepping and publishing frames, and ``activate`` again goes on from the
same state (while inactive the node answers its services and parameters and reports on
``/diagnostics``, as while paused); ``cleanup`` (and ``shutdown``) stops the threads and
destroys the publishers, services and timers configure made. Transitions the state machine
does not allow are refused by it (``ChangeState`` answers ``success: false``).
"""
from __future__ import annotations

from typing import Callable

from lifecycle_msgs.msg import Transition
from modal_spring_ros.bags.files.writer import BagError
from modal_spring_ros.core.model.scene import SceneError
from modal_spring_ros.core.worker import WorkerError
from modal_spring_ros.ros.node import ModalSpringNode, STOP_ORDER
from modal_spring_ros.ros.process.stop_signals import StopSignals
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.lifecycle import (LifecycleNode, LifecycleNodeMixin, LifecycleState,
                             TransitionCallbackReturn)
from rclpy.node import Node

#: what configure may fail with: the reason is logged and the node stays unconfigured
CONFIGURE_ERRORS = (SceneError, ValueError, WorkerError, BagError)
#: lifecycle_msgs/Transition ids by name, for what is logged
TRANSITIONS = {Transition.TRANSITION_CONFIGURE: 'configure',
               Transition.TRANSITION_CLEANUP: 'cleanup',
               Transition.TRANSITION_ACTIVATE: 'activate',
               Transition.TRANSITION_DEACTIVATE: 'deactivate',
               Transition.TRANSITION_UNCONFIGURED_SHUTDOWN: 'shutdown',
               Transition.TRANSITION_INACTIVE_SHUTDOWN: 'shutdown',
               Transition.TRANSITION_ACTIVE_SHUTDOWN: 'shutdown'}
#: the entity lists of rclpy's Node that configure adds to, with the method that destroys one
ENTITIES = (('publishers', 'destroy_publisher'), ('services', 'destroy_service'),
            ('timers', 'destroy_timer'), ('guards', 'destroy_guard_condition'),
            ('subscriptions', 'destroy_subscription'))


class AnsweringLifecycleNode(LifecycleNode):
    """
    rclpy's lifecycle node with its lifecycle services in a reentrant callback group.

    ``LifecycleNode`` puts them in the node's default (mutually exclusive) group, so while a
    transition runs (a configure that computes modes for a minute) ``get_state`` and the other
    queries wait behind it. Here they are answered on the executor's other thread meanwhile
    (the state is then ``configuring``, as rclcpp's nodes answer), and a second transition asked
    during one is refused by the state machine.
    """

    def __init__(self, node_name: str, **kwargs):
        Node.__init__(self, node_name, **kwargs)
        LifecycleNodeMixin.__init__(self, enable_communication_interface=True,
                                    callback_group=ReentrantCallbackGroup())


class ManagedModalSpringNode(ModalSpringNode, AnsweringLifecycleNode):
    """The streaming node, configured, activated and cleaned up through its lifecycle."""

    def __init__(self, stop: StopSignals | None = None, **kwargs):
        self._before: dict[str, list] | None = None   # entities before configure (None: not)
        super().__init__(stop=stop, **kwargs)
        # rclpy's ChangeState service raises out of the executor on a transition the state
        # does not have (activate while unconfigured), which would end the node: refused here
        service = self._service_change_state
        service.callback = self._refusing(service.callback)

    def _refusing(self, change_state: Callable) -> Callable:
        def answer(request, response):
            try:
                return change_state(request, response)
            except _rclpy.RCLError as exc:
                transition = request.transition
                name = transition.label or TRANSITIONS.get(transition.id, str(transition.id))
                self.get_logger().warning(
                    f'transition {name} refused: not allowed from '
                    f'the state {self._state_machine.current_state[1]} ({exc})')
                response.success = False
                return response
        return answer

    def _start(self) -> None:
        """Unconfigured: the parameters only."""
        self._declare_parameters()

    def _entities(self) -> dict[str, list]:
        return {name: list(getattr(self, name)) for name, _ in ENTITIES}

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        before = self._entities()
        try:
            self._build()
        except CONFIGURE_ERRORS as exc:
            self.get_logger().error(f'configure failed: {exc}')
            self._release(before)
            return TransitionCallbackReturn.FAILURE
        self._before = before
        # the threads run, held: requests (~/reset, parameters) are answered while inactive
        self._thread.suspend()
        self._begin()
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._thread.resume()
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._thread.suspend()
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._release(self._before)
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        if self._before is not None:
            self._release(self._before)
        return TransitionCallbackReturn.SUCCESS

    def _release(self, before: dict[str, list] | None) -> None:
        """Stop what configure started and destroy the entities it made (back to unconfigured)."""
        params = getattr(self, '_params', None)
        self.stop()
        if params is not None:
            params.unlisten()
        for name, destroy in ENTITIES if before is not None else ():
            kept = {id(entity) for entity in before[name]}
            for entity in [e for e in getattr(self, name) if id(e) not in kept]:
                getattr(self, destroy)(entity)
        for name, _ in STOP_ORDER:
            setattr(self, name, None)
        self._params = None
        self._before = None
