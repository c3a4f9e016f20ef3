"""
The node's parameters: requests validated on set, changes committed after it.

Two views of the parameters: ``values``, what was set (and what the node answers with), and
``applied``, what the run has (a slow change still being prepared is in the first only).

- The on-set callback only validates: values, ranges and the band's edges at once, and the
  slow part (modes, operators, a new simulation) in the change preparer
  (:mod:`~modal_spring_ros.ros.changes.change_preparer`), answered with its outcome or as pending.
  It changes nothing, so a request refused after it (by rclpy, or by a callback added later)
  leaves the run as it was.
- The post-set callback commits: the views take the new values, fast settings (rates, the
  clock) reach the stream, and the preparer may hand the prepared change to the run.
"""
from __future__ import annotations

import threading
from typing import Any, Callable

from modal_spring_ros.core.model.scene import SceneError
from modal_spring_ros.core.simulations import Simulation
from modal_spring_ros.core.worker import WorkerError
from modal_spring_ros.ros.changes.change_preparer import ChangePreparer, ChangeRefused, describe
from modal_spring_ros.ros.changes.parameter_changes import ChangePlanner
from modal_spring_ros.ros.changes.requests import Request
from modal_spring_ros.ros.parameters import (CLOCK_OFFSET, config_from_parameters, FREQUENCIES,
                                             PARAMETERS, SLOW_PARAMETERS)
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

#: the parameters the node reports: every request but the node's own is refused, saying why
REPORTED = {
    FREQUENCIES: 'the node reports the frequencies of the modes it has computed',
    CLOCK_OFFSET: 'the node moves it on at a reset or a divergence, so that published time '
                  'never goes back',
}


class NodeParameters:
    """
    Validates, prepares and commits the parameter changes of one node.

    ``running()`` returns the simulation being stepped, ``submit(request)`` hands a prepared
    change to the simulation thread, ``settings_changed()`` tells it that fast settings changed
    and ``enable_clock()`` starts ``/clock``.
    """

    def __init__(self, node: Node, planner: ChangePlanner, running: Callable[[], Simulation],
                 submit: Callable[[Request], None], settings_changed: Callable[[], None],
                 enable_clock: Callable[[], None]):
        self._node = node
        self._planner = planner
        self._running = running
        self._submit = submit
        self._settings_changed = settings_changed
        self._enable_clock = enable_clock
        self._lock = threading.Lock()                # guards the two views
        self._values = {name: node.get_parameter(name).value for name in PARAMETERS}
        self._applied = dict(self._values)
        self._own_update = threading.local()         # the node setting parameters itself
        self._asked: dict[str, Any] = {}             # values the run started without
        self.preparer = ChangePreparer(self._prepare, self._commit, self._revert)

    @property
    def values(self) -> dict[str, Any]:
        """Return the parameters as set (a slow change still being prepared included)."""
        return self._values

    def applied(self) -> dict[str, Any]:
        """Return the parameters the run has."""
        with self._lock:
            return dict(self._applied)

    def start_from(self, first: dict[str, Any]) -> None:
        """
        Say the run was built with ``first`` in place of these parameters' values.

        (a quicker start, :mod:`~modal_spring_ros.ros.start.start_up`); :meth:`prepare_asked` then
        prepares the values asked for as a change. Before :meth:`listen`.
        """
        with self._lock:
            self._asked = {name: self._values[name] for name in first}
            self._applied.update(first)

    def prepare_asked(self) -> None:
        """Prepare the values the run started without (in the preparer: the stream runs)."""
        asked, self._asked = self._asked, {}
        if not asked:
            return
        self._node.get_logger().info(f'streaming while {describe(asked)} is prepared')
        accepted, reason = self.preparer.request(asked)
        if accepted:
            self.preparer.parameters_set()      # they are set: they were the node's own
        else:
            self._revert(asked, reason)

    def listen(self) -> None:
        """Take requests from now on."""
        self._node.add_on_set_parameters_callback(self._on_set)
        self._node.add_post_set_parameters_callback(self._after_set)

    def unlisten(self) -> None:
        """Take no more requests (the node's parts are released: a managed node cleaned up)."""
        self._node.remove_on_set_parameters_callback(self._on_set)
        self._node.remove_post_set_parameters_callback(self._after_set)

    # -- the parameter services' callbacks -----------------------------------------------------
    def _own(self) -> bool:
        return getattr(self._own_update, 'active', False)

    def _on_set(self, params: list[Parameter]) -> SetParametersResult:
        """Validate a request and prepare its slow part, answered within ``answer_within_s``."""
        if self._own():                              # the node itself: frequencies, reverts
            return SetParametersResult(successful=True)
        reported = [p.name for p in params if p.name in REPORTED]
        if reported:
            return self._refused(f'{reported[0]} is read-only: {REPORTED[reported[0]]}')
        incoming = {p.name: p.value for p in params if p.name in PARAMETERS}
        with self._lock:
            requested = dict(self._values, **incoming)
        try:
            config = config_from_parameters(requested)   # values, ranges, the band's edges
        except ValueError as exc:
            return self._refused(str(exc))
        slow = {k: v for k, v in incoming.items() if k in SLOW_PARAMETERS}
        empty = (self._planner.keeps_no_mode(config.band)
                 if slow and config.method == 'modal' and not config.auto else '')
        if empty:                                    # decided by the modes computed already
            return self._refused(empty)
        reason = ''
        if slow:
            accepted, reason = self.preparer.request(slow)
            if not accepted:
                return self._refused(reason)
            if reason:      # rclpy answers a success without its reason: said in the log
                self._node.get_logger().info(f'parameter change accepted, {reason}')
        return SetParametersResult(successful=True, reason=reason)

    def _after_set(self, params: list[Parameter]) -> None:
        """Commit what is set: the views, the fast settings, and the slow change's hand-over."""
        if self._own():
            return
        incoming = {p.name: p.value for p in params if p.name in PARAMETERS}
        with self._lock:
            self._values = dict(self._values, **incoming)
            self._applied.update({k: v for k, v in incoming.items() if k not in SLOW_PARAMETERS})
            clock = self._values['publish_clock']
        if clock:
            self._enable_clock()
        if SLOW_PARAMETERS.intersection(incoming):
            self.preparer.parameters_set()
        self._settings_changed()

    def _refused(self, reason: str) -> SetParametersResult:
        self._node.get_logger().warning(f'parameter change rejected: {reason}')
        return SetParametersResult(successful=False, reason=reason)

    # -- the change preparer's thread ----------------------------------------------------------
    def _prepare(self, incoming: dict) -> Request | None:
        try:
            return self._planner.plan(self.applied(), incoming, self._running())
        except (ValueError, SceneError, WorkerError) as exc:
            raise ChangeRefused(str(exc)) from exc

    def _commit(self, incoming: dict, request: Request | None) -> None:
        with self._lock:
            self._applied.update(incoming)
        self._publish_frequencies()
        if request is not None:
            self._submit(request)
            self._node.get_logger().info(f'the run takes {describe(incoming)}')

    def _revert(self, incoming: dict, reason: str) -> None:
        """Set back what a change answered as accepted set, unless something newer has."""
        with self._lock:
            back = {k: self._applied[k] for k, v in incoming.items() if self._values[k] == v}
            self._values.update(back)
        self._node.get_logger().error(f'parameter change {describe(incoming)} failed after it '
                                      f'was accepted: {reason}; back to {describe(back)}')
        if back:
            self._set_own([Parameter(k, value=v) for k, v in back.items()])

    def _set_own(self, params: list[Parameter]) -> None:
        self._own_update.active = True
        try:
            self._node.set_parameters(params)
        finally:
            self._own_update.active = False

    def report(self, name: str, value: Any) -> None:
        """Set a parameter the node reports (:data:`REPORTED`), as the node itself."""
        self._set_own([Parameter(name, value=value)])

    def _publish_frequencies(self) -> None:
        """Update modal.frequencies_hz when a band made the node compute more modes."""
        freqs = self._planner.basis.frequencies_hz.tolist()
        if len(freqs) == len(self._node.get_parameter(FREQUENCIES).value):
            return
        self._set_own([Parameter(FREQUENCIES, value=freqs)])
