"""
The services that drive the run: the project's own and ROS 2's standard simulation services.

Every call becomes one request for the simulation thread (:mod:`.requests`), awaited without
holding an executor thread and answered with what happened:

* ``~/reset`` (Trigger), ``~/pause`` (SetBool), ``~/step`` (Trigger: one frame, while paused);
* ROS 2's standard ``simulation_interfaces``, under the same names a harness finds on Gazebo's
  server node: ``~/step_simulation`` (StepSimulation: ``steps`` frames of a paused run, each
  published), ``~/set_simulation_state`` (SetSimulationState: play, pause, or stop, which pauses
  the run at its rest state and t = 0), ``~/get_simulation_state`` (GetSimulationState: playing,
  paused, or stopped: paused at t = 0), ``~/reset_simulation`` (ResetSimulation: time and state
  together) and ``~/get_simulator_features`` (GetSimulatorFeatures). Served where the package
  imports: a ROS install has it, the PyPI path generates it (``.ci/interfaces``).

One step of the standard is one iteration of the node's loop: a published frame, ``1 /
publish_rate_hz`` of simulated time (times ``realtime_factor`` when set), as ``~/step`` makes.
"""
from __future__ import annotations

import contextlib
from typing import Callable

from modal_spring_ros.ros.changes.requests import applied_within, Pause, Request, Reset, Step
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from std_srvs.srv import SetBool, Trigger

try:        # not among the ROS wheels: generated on the PyPI path (.ci/interfaces)
    from simulation_interfaces.msg import Result, SimulationState, SimulatorFeatures
    from simulation_interfaces.srv import (GetSimulationState, GetSimulatorFeatures,
                                           ResetSimulation, SetSimulationState, StepSimulation)
except ImportError:
    STANDARD = False
else:
    STANDARD = True

#: how long a request may wait for the simulation thread before its answer says so
SERVICE_TIMEOUT_S = 5.0
#: and how much longer for each frame a standard step call asks for
FRAME_TIMEOUT_S = 1.0
#: most frames one standard step call may ask for (a harness steps in smaller calls)
MAX_STEP_FRAMES = 100_000
#: how often the awaiting coroutines look at their deadline
SERVICE_WAKE_S = 0.25
#: what a step and a reset are here, for a harness reading the features
ABOUT = ('modal_spring_ros: one step is one published frame (1 / publish_rate_hz of simulated '
         'time, times realtime_factor when set); a reset puts time and state back together; '
         'stopped is paused at the rest state at t = 0')


class RunServices:
    """
    The run's services on ``node``, answered by the simulation thread.

    ``submit`` hands a request to the simulation thread; ``paused`` and ``at_start`` read the
    run (paused; at t = 0, as a reset leaves it).
    """

    def __init__(self, node: Node, submit: Callable[[Request], None],
                 paused: Callable[[], bool], at_start: Callable[[], bool]):
        self._submit, self._paused, self._at_start = submit, paused, at_start
        group = ReentrantCallbackGroup()       # awaiting coroutines: no thread held
        self._answered = node.create_guard_condition(lambda: None, callback_group=group)
        # wall-time wake-ups on the steady clock: under use_sim_time a timer on the ROS clock
        # would stop with a paused /clock (and with it the deadlines)
        node.create_timer(SERVICE_WAKE_S, lambda: None, callback_group=group,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))
        services = [(Trigger, '~/reset', self._on_reset), (SetBool, '~/pause', self._on_pause),
                    (Trigger, '~/step', self._on_step)]
        if STANDARD:
            services += [(StepSimulation, '~/step_simulation', self._on_step_simulation),
                         (SetSimulationState, '~/set_simulation_state', self._on_set_state),
                         (GetSimulationState, '~/get_simulation_state', self._on_get_state),
                         (ResetSimulation, '~/reset_simulation', self._on_reset_simulation),
                         (GetSimulatorFeatures, '~/get_simulator_features', self._on_features)]
        for kind, name, callback in services:
            node.create_service(kind, name, callback, callback_group=group)

    async def apply(self, request: Request, timeout: float = SERVICE_TIMEOUT_S) -> str:
        """Hand ``request`` over, await its answer; return '' when applied, else why not."""
        request.on_finish = self._wake
        self._submit(request)
        if await applied_within(request, timeout):
            return ''
        return request.message or 'not applied in time: the simulation is busy'

    def _wake(self) -> None:     # an answer a service awaits is ready (unless ROS is gone)
        with contextlib.suppress(RuntimeError):     # InvalidHandle, RCLError: shutting down
            self._answered.trigger()

    # -- the project's own ---------------------------------------------------------------------
    async def _answer(self, request: Request, response):
        failed = await self.apply(request)
        response.success, response.message = not failed, failed or request.message
        return response

    async def _on_reset(self, _request, response):
        return await self._answer(Reset(), response)

    async def _on_pause(self, request, response):
        return await self._answer(Pause(paused=bool(request.data)), response)

    async def _on_step(self, _request, response):
        return await self._answer(Step(), response)

    # -- ROS 2's standard ----------------------------------------------------------------------
    def state(self) -> int:
        """Return the run's ``SimulationState`` (stopped: paused at t = 0)."""
        if not self._paused():
            return SimulationState.STATE_PLAYING
        return SimulationState.STATE_STOPPED if self._at_start() else SimulationState.STATE_PAUSED

    async def _on_step_simulation(self, request, response):
        frames = int(request.steps)
        if not self._paused():
            return _result(response, Result.RESULT_OPERATION_FAILED,
                           'the simulation is playing: pause it first (set_simulation_state)')
        if frames > MAX_STEP_FRAMES:
            return _result(response, Result.RESULT_OPERATION_FAILED,
                           f'{frames} steps in one call: at most {MAX_STEP_FRAMES}')
        if frames == 0:
            return _result(response, Result.RESULT_OK, '')
        failed = await self.apply(Step(frames=frames),
                                  SERVICE_TIMEOUT_S + FRAME_TIMEOUT_S * frames)
        return _result(response, Result.RESULT_OPERATION_FAILED if failed else Result.RESULT_OK,
                       failed)

    async def _on_set_state(self, request, response):
        target, now = request.state.state, self.state()
        if target == now:
            return _result(response, response.ALREADY_IN_TARGET_STATE, 'already in that state')
        if target == SimulationState.STATE_PLAYING:
            failed = await self.apply(Pause(paused=False))
        elif target == SimulationState.STATE_PAUSED:
            if now == SimulationState.STATE_STOPPED:
                return _result(response, response.INCORRECT_TRANSITION,
                               'stopped: play or step it first')
            failed = await self.apply(Pause(paused=True))
        elif target == SimulationState.STATE_STOPPED:
            failed = await self.apply(Pause(paused=True)) or await self.apply(Reset())
        else:
            return _result(response, Result.RESULT_FEATURE_UNSUPPORTED,
                           f'state {target}: the node plays, pauses and stops (quit it with '
                           'SIGINT or its lifecycle; it has one world)')
        return _result(response, response.STATE_TRANSITION_ERROR if failed
                       else Result.RESULT_OK, failed)

    async def _on_get_state(self, _request, response):
        response.state.state = self.state()
        return _result(response, Result.RESULT_OK, '')

    async def _on_reset_simulation(self, request, response):
        both = ResetSimulation.Request.SCOPE_TIME | ResetSimulation.Request.SCOPE_STATE
        scope = request.scope
        if scope != ResetSimulation.Request.SCOPE_DEFAULT and scope & both != both:
            return _result(response, Result.RESULT_FEATURE_UNSUPPORTED,
                           f'scope {scope}: time and state are reset together (SCOPE_ALL)')
        failed = await self.apply(Reset())
        return _result(response, Result.RESULT_OPERATION_FAILED if failed else Result.RESULT_OK,
                       failed)

    async def _on_features(self, _request, response):
        response.features.features = [
            SimulatorFeatures.SIMULATION_RESET, SimulatorFeatures.SIMULATION_STATE_GETTING,
            SimulatorFeatures.SIMULATION_STATE_SETTING, SimulatorFeatures.SIMULATION_STATE_PAUSE,
            SimulatorFeatures.STEP_SIMULATION_SINGLE, SimulatorFeatures.STEP_SIMULATION_MULTIPLE]
        response.features.custom_info = ABOUT
        return response


def _result(response, code: int, message: str):
    """Fill a standard response's ``result`` and return the response."""
    response.result.result, response.result.error_message = code, message
    return response
