"""
The node's subscriptions on a small node of their own, spun in their own paced thread.

rclpy spends a fraction of a millisecond of interpreter time on every message a subscription takes,
more the more entities its node's executor waits on (the streaming node has its parameter services,
its own services, timers and publishers: about 1 ms a message). A publisher sending clicks or poses
at a kilohertz would then hold the interpreter lock most of the time and starve the simulation
thread: the stream fell from 30 to 6-11 frames a second under 780 clicks a second. So the inputs
(:mod:`~modal_spring_ros.ros.inputs.subscriptions`) subscribe on a companion node,
``<name>_inputs`` in the same namespace, which has no parameter services and is spun by its own
single-threaded executor, and that executor takes at most ``MAX_INPUT_RATE_HZ`` messages a second
and spends at most ``MAX_INPUT_CPU_SHARE`` of one core's time on them (what a message costs varies
with the machine and its load: the thread measures its own CPU time and waits in proportion). A
faster sender waits in its DDS queue (keep-last: the newest are kept) and costs this process
nothing more (the inputs keep only their newest message waiting, so what is taken is never late).
Every input stays what it was (topics, remapping), and a person's clicks or a robot's poses at tens
of hertz are taken as they come.

TF is heard on a companion of its own, ``<name>_tf``, paced far more loosely (``TF_CPU_SHARE``):
``/tf`` carries every frame of a robot at its rate and this node's own broadcasts with every
frame of the stream, and each message must be taken (the newest of each link is the tree), so a
pace meant for a flood of clicks held its queue full and the clamp that follows a frame trailed
it by most of a second. Paced this loosely it keeps up, as tf2_ros's own listener thread does;
the share still bounds what a flood of ``/tf`` may take from the stream.
"""
from __future__ import annotations

import threading
import time

from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

#: most messages the inputs take a second (all topics together)
MAX_INPUT_RATE_HZ = 500.0
#: largest share of one core's time the input thread spends taking messages (a tenth stalled
#: the stream 1 run in 8 under a flood with three busy processes on two cores; this, none)
MAX_INPUT_CPU_SHARE = 0.05
#: longest the input thread waits for a message before it checks that it should go on, s
WAIT_SLICE_S = 0.1
#: the TF companion: most messages a second, and largest share of a core
TF_MAX_RATE_HZ, TF_CPU_SHARE = 5000.0, 0.5


class InputNode:
    """A companion of ``node`` for its subscriptions, spun in its own thread once started."""

    def __init__(self, node: Node, max_rate_hz: float = MAX_INPUT_RATE_HZ,
                 max_cpu_share: float = MAX_INPUT_CPU_SHARE, suffix: str = 'inputs'):
        """
        Make ``<node>_<suffix>`` in ``node``'s namespace, spun by ``modal_spring_<suffix>``.

        ``max_rate_hz`` and ``max_cpu_share`` pace the thread's callbacks.
        """
        name = f'{node.get_name()}_{suffix}'
        # the executor before the node that others can see (a Ctrl-C inside an executor's
        # constructor leaves a half-built one whose finaliser prints a traceback)
        self._executor = SingleThreadedExecutor(context=node.context)
        # its own name even under a global ``__node:=`` remap, which would otherwise give the
        # companion the streaming node's name
        self.node = Node(name, namespace=node.get_namespace(), context=node.context,
                         start_parameter_services=False,
                         cli_args=['--ros-args', '-r', f'__node:={name}'])
        self._gap = 1.0 / float(max_rate_hz)
        self._cpu_share = float(max_cpu_share)
        self._executor.add_node(self.node)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f'modal_spring_{suffix}',
                                        daemon=True)

    def start(self) -> None:
        self._thread.start()

    def _run(self) -> None:
        # one callback at most per gap, and the thread's CPU time at most its share of the
        # time: a flood waits in DDS, not in this interpreter
        while not self._stop.is_set() and self._executor.context.ok():
            returned = time.monotonic()
            cpu = time.thread_time()
            try:
                self._executor.spin_once(timeout_sec=WAIT_SLICE_S)
            except ExternalShutdownException:
                return
            except Exception:
                # Ctrl-C shuts the context down from rclpy's signal handler, at any moment:
                # after the check above, the wait itself fails (RCLError, invalid handles)
                if self._executor.context.ok():
                    raise
                return
            spent = time.thread_time() - cpu
            period = max(self._gap, spent / self._cpu_share)
            self._stop.wait(max(0.0, returned + period - time.monotonic()))

    def close(self, timeout: float = 5.0) -> None:
        """Stop taking messages, and destroy the companion node."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout)
        self._executor.shutdown(timeout_sec=timeout)
        self.node.destroy_node()
