"""Run the real node as a subprocess and talk to it over DDS from an rclpy client node."""
from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading
import time

from modal_spring_ros.bags.files.reader import BagReader
from modal_spring_ros.bags.files.sim_time import SOURCE
from modal_spring_ros.bags.messages.pointcloud import xyz
from modal_spring_ros.bags.messages.stamps import to_nanoseconds, to_seconds
from modal_spring_ros.ros.node import ModalSpringNode
from modal_spring_ros.ros.process.pooled_executor import PooledExecutor
from modal_spring_ros.ros.process.stop_signals import end_ros, spin_until_stopped, StopSignals
from modal_spring_ros.ros.tools.resimulate import resimulate
from modal_spring_ros.scenes.resources import executable
import numpy as np
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from sensor_msgs.msg import TimeReference

# The ROS_DOMAIN_ID a user set is kept; otherwise one DDS domain per test session, so that
# parallel sessions stay apart. Discovery on loopback only.
DOMAIN_ID = (int(os.environ['ROS_DOMAIN_ID']) if os.environ.get('ROS_DOMAIN_ID', '').isdigit()
             else 20 + os.getpid() % 70)
os.environ['ROS_DOMAIN_ID'] = str(DOMAIN_ID)
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'


def node_of(status) -> str:
    """Return the fully qualified name of the node a ``DiagnosticStatus`` is about."""
    return next((kv.value for kv in status.values if kv.key == 'node'), '')


def streaming_statuses(diags: list, prefix: str) -> list:
    """
    Return the /diagnostics statuses of the node under ``prefix`` once it streams.

    ``diags``: (receipt time, DiagnosticArray) as :meth:`Client.collect` keeps them; the statuses
    a node publishes while it prepares its first frame (``starting: ...``) are left out.
    """
    return [d.status[0] for _, d in list(diags) if node_of(d.status[0]).startswith(prefix)
            and not d.status[0].message.startswith('starting: ')]


def reported_per_second(diags: list, prefix: str, key: str, start: float, end: float) -> float:
    """
    Return how fast the node under ``prefix`` says ``key`` grew between two times, a second.

    From its reports on /diagnostics (received between ``start`` and ``end``, monotonic): what
    the node did, whatever a reader on a busy machine keeps up with. The node reports every
    second; where fewer than two reached this process within the window (a busy machine delays
    its reader), the last one before and the first one after it bound the window instead.
    """
    every = sorted((t, float(v[key])) for t, v in
                   ((t, {kv.key: kv.value for kv in d.status[0].values}) for t, d in list(diags))
                   if v.get('node', '').startswith(prefix) and key in v)
    reports = [r for r in every if start <= r[0] < end]
    if len(reports) < 2:
        before = [r for r in every if r[0] < start][-1:]
        after = [r for r in every if r[0] >= end][:1]
        reports = before + reports + after
    assert len(reports) >= 2, reports
    (t0, n0), (t1, n1) = reports[0], reports[-1]
    return (n1 - n0) / (t1 - t0)


def published_rate(diags: list, prefix: str, start: float, end: float) -> float:
    """Return the frames a second the node under ``prefix`` says it published (its reports)."""
    return reported_per_second(diags, prefix, 'frames published', start, end)


def assert_resimulates_exactly(capture, again, changes: int) -> int:
    """
    Re-simulate a node's capture (``record.bag``) into ``again``; return its frame count.

    The capture is finalised with ``changes`` parameter events, and the re-run gives every
    frame at its time, to float32 round-off.
    """
    recording = BagReader(capture)
    assert recording.finalised and recording.topics['/parameter_events'].count == changes
    count = resimulate(capture, again)
    t_rec, x_rec = recording.points()
    t_new, x_new = BagReader(again).points()
    assert count == len(t_rec) and np.array_equal(t_new, t_rec)
    np.testing.assert_allclose(x_new, x_rec, rtol=0, atol=2e-6)
    return count


#: lines shown before a native fault's report
FAULT_CONTEXT_LINES = 6


def stderr_excerpt(err: str, size: int = 2000) -> str:
    """
    Return what a failure message should show of a process's ``err``: its end, or its fault.

    A crash in native code prints the fault and every thread's stack (faulthandler) followed by
    a long list of extension modules; the list would fill the end, so the fault is shown, with
    the lines just before it (what the native code printed as it failed: a C++ exception's
    ``terminate called after throwing ...``, a middleware's error).
    """
    start = err.find('Fatal Python error')
    if start < 0:
        return err[-size:]
    start = err.rfind('\n', 0, start)
    for _ in range(FAULT_CONTEXT_LINES):
        start = err.rfind('\n', 0, max(start, 0))
    start = max(start + 1, 0)
    end = err.find('Extension modules', start)
    return err[start:end if end >= 0 else None][:4 * size]


def console_script(name: str) -> str:
    """Return the installed console script, found as ``ros2 run`` would (or in the venv)."""
    return str(executable(name))


class NodeProcess:
    """
    ``modal_spring_node`` with ``--ros-args -p`` overrides, in its own process group.

    What the process prints is read as it comes (two reader threads): a test can wait for a line
    of one process among several of one name, and a chatty node never blocks on a full pipe.
    """

    def __init__(self, *params: str, namespace: str = '',
                 executable: str = 'modal_spring_node', argv: list[str] | None = None):
        """Start the node; ``argv``, when given, is the whole command line (no other options)."""
        args = argv
        if args is None:
            args = [console_script(executable)]
            ros_args = [x for p in params for x in ('-p', p)]
            if namespace:
                ros_args += ['-r', f'__ns:=/{namespace}']
            if ros_args:
                args += ['--ros-args'] + ros_args
        self.proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True, env=dict(os.environ), start_new_session=True)
        self._out: list[str] = []
        self._err: list[str] = []
        self._readers = [threading.Thread(target=lines.extend, args=(pipe,), daemon=True)
                         for lines, pipe in ((self._out, self.proc.stdout),
                                             (self._err, self.proc.stderr))]
        for reader in self._readers:
            reader.start()

    def stderr(self) -> str:
        """Return what the process has printed to stderr so far."""
        return ''.join(list(self._err))

    def wait(self, timeout: float) -> tuple[int, str, str]:
        """
        Wait for the process to end; return its exit status, stdout and stderr.

        Whatever it leaves running in its process group (a node it started, were it to crash) is
        killed: never left publishing into the next test's graph.
        """
        self.proc.wait(timeout=timeout)
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(self.proc.pid, signal.SIGKILL)
        for reader in self._readers:
            reader.join(timeout=10.0)
        return self.proc.returncode, ''.join(self._out), ''.join(self._err)

    def interrupt(self, timeout: float = 15.0,
                  sig: signal.Signals = signal.SIGINT) -> tuple[int, str, str]:
        """
        SIGINT (as Ctrl-C would), or ``sig``; return the exit status and what it printed.

        A node still running after ``timeout`` is killed and the test fails with what it printed
        (never left running into the next test).
        """
        self.proc.send_signal(sig)
        try:
            return self.wait(timeout)
        except subprocess.TimeoutExpired:
            _, err = self.kill()
            raise AssertionError(f'node still running {timeout} s after {sig.name}; '
                                 f'stderr: {stderr_excerpt(err)}') from None

    def kill(self) -> tuple[str, str]:
        """SIGKILL to the whole process group; returns what the process printed."""
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(self.proc.pid, signal.SIGKILL)
        with contextlib.suppress(subprocess.TimeoutExpired):
            return self.wait(10.0)[1:]
        return ''.join(self._out), ''.join(self._err)


class Client:
    """
    A test node in its own context, spun by a background thread.

    The thread spins in short slices and is joined before anything is destroyed:
    ``Executor.shutdown`` does not wait for a ``spin`` running in another thread, and cleaning
    up under it races with the wait (ros2/rclpy#968); destroying a node or a context that
    another thread waits on can deadlock inside the middleware.
    """

    SLICE_S = 0.05
    MATCH_S = 0.3

    def __init__(self, name: str = 'test_client'):
        self.context = Context()
        rclpy.init(context=self.context, domain_id=DOMAIN_ID)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.error: BaseException | None = None
        self._clients: dict = {}
        self._clients_lock = threading.Lock()
        self._stop = threading.Event()
        self._closed = False
        self._thread = threading.Thread(target=self._spin, name=f'{name}_spin', daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        try:
            while not self._stop.is_set() and self.context.ok():
                self.executor.spin_once(timeout_sec=self.SLICE_S)
        except BaseException as exc:  # reported by close(), not lost in the thread
            self.error = exc

    def collect(self, msg_type, topic: str, qos: int = 50) -> list:
        """Subscribe and return the list messages are appended to (with receive time)."""
        received: list = []
        self.node.create_subscription(
            msg_type, topic, lambda m: received.append((time.monotonic(), m)), qos)
        return received

    def call(self, srv_type, name: str, request, timeout: float = 20.0,
             resend_s: float | None = None):
        """
        Call a service and wait for its answer.

        One client per service, kept: a client created per call can send its request before the
        server has matched its response reader, and DDS then drops the answer (Fast DDS waits
        100 ms for that match, ros2/rmw_fastrtps#390; a busy machine can take longer). A new
        client therefore gives discovery a moment before its first request, and a query that
        may safely be asked twice (``resend_s``) is asked again when unanswered that long.
        """
        with self._clients_lock:
            client = self._clients.get((srv_type, name))
            if client is None:
                client = self.node.create_client(srv_type, name)
                if not client.wait_for_service(timeout_sec=timeout):
                    raise TimeoutError(f'service {name} not available')
                time.sleep(self.MATCH_S)
                self._clients[(srv_type, name)] = client
        end = time.monotonic() + timeout
        while True:
            future = client.call_async(request)
            ask_again = time.monotonic() + (resend_s or timeout)
            while not future.done() and time.monotonic() < min(end, ask_again):
                time.sleep(0.01)
            if future.done():
                return future.result()
            if time.monotonic() >= end:
                raise TimeoutError(f'service {name} did not answer')
            client.remove_pending_request(future)

    def set_parameters(self, node: str, atomically: bool = False, timeout: float = 20.0,
                       **values):
        from rcl_interfaces.srv import SetParameters, SetParametersAtomically
        params = [Parameter(k.replace('__', '.'), value=v).to_parameter_msg()
                  for k, v in values.items()]
        if atomically:
            req = SetParametersAtomically.Request(parameters=params)
            return [self.call(SetParametersAtomically, f'/{node}/set_parameters_atomically',
                              req, timeout).result]
        return self.call(SetParameters, f'/{node}/set_parameters',
                         SetParameters.Request(parameters=params), timeout).results

    def get_parameters(self, node: str, *names: str) -> list:
        from rcl_interfaces.srv import GetParameters
        res = self.call(GetParameters, f'/{node}/get_parameters',
                        GetParameters.Request(names=list(names)))
        return [Parameter.from_parameter_msg(
            __import__('rcl_interfaces.msg', fromlist=['Parameter']).Parameter(
                name=n, value=v)).value for n, v in zip(names, res.values)]

    def close(self) -> None:
        """Stop and join the spin thread, then destroy the node and the context (once)."""
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        self._thread.join(timeout=10.0)
        if self._thread.is_alive():
            raise RuntimeError("the client's spin thread did not stop within 10 s")
        self.executor.shutdown(timeout_sec=0.0)
        self.node.destroy_node()
        end_ros(self.context)
        if self.error is not None:
            raise RuntimeError(f"the client's executor failed: {self.error!r}")

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class SimTimes:
    """The simulation time of each frame, as the node publishes it beside them on sim_time."""

    def __init__(self):
        """Start empty: :meth:`subscribe` before the frames asked about arrive."""
        self._times: dict[int, float] = {}

    def subscribe(self, client: Client, topic: str = '/sim_time') -> SimTimes:
        """Take the node's ``sim_time`` (``topic``) through ``client``; return self."""
        client.node.create_subscription(TimeReference, topic, self._keep, 200)
        return self

    def _keep(self, reference: TimeReference) -> None:
        if reference.source == SOURCE:
            self._times[to_nanoseconds(reference.header.stamp)] = to_seconds(reference.time_ref)

    def known(self, frame) -> float | None:
        """Return a frame's simulation time if its sim_time has come, else None (no wait)."""
        return self._times.get(to_nanoseconds(frame.header.stamp))

    def __call__(self, frame) -> float:
        """Return the simulation time, s, of a frame (a message with a header) received."""
        key = to_nanoseconds(frame.header.stamp)
        assert wait_for(lambda: key in self._times, 2.0), 'no sim_time for the frame'
        return self._times[key]

    def fastest(self, points: list) -> float:
        """
        Return the fastest any particle moved between two frames, m per simulated second.

        ``points``: (receipt time, PointCloud2) as :meth:`Client.collect` keeps them; frames whose
        sim_time has not come are left out. Judged per simulated second, a frame lost on a busy
        machine doubles a step, not a speed; a state lost in a switch moves the object by its
        displacement in one frame. At least 30 frames, every one finite.
        """
        timed = [(t, xyz(m)) for _, m in list(points) if (t := self.known(m)) is not None]
        assert len(timed) > 30 and all(np.isfinite(c).all() for _, c in timed), len(timed)
        return max(np.abs(b - a).max() / (tb - ta)
                   for (ta, a), (tb, b) in zip(timed, timed[1:]) if tb > ta)


def wait_for(predicate, timeout: float, interval: float = 0.02) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(interval)
    return predicate()


def frames_since(received: list, start: float, count: int, timeout: float = 20.0) -> list:
    """
    Wait for ``count`` messages received after ``start`` (monotonic); return all of them.

    A stream that goes on reaches the count; a busy machine may slow it but never fails the
    test: how steady the stream stays under load is measured against the same run's steady
    rate where a test means it (``test_node_stress``), never as a fixed rate.
    """
    def window():
        return [m for t, m in list(received) if t > start]
    assert wait_for(lambda: len(window()) >= count, timeout), (
        f'{len(window())} messages in {time.monotonic() - start:.1f} s, {count} expected')
    return window()


@contextlib.contextmanager
def running_node(*params: str, namespace: str, argv: list[str] | None = None):
    """
    Return a node in ``namespace`` (or started by the command line ``argv``).

    The node must end cleanly on SIGINT afterwards. Whatever fails, it does not outlive the test.
    A client made before it sees its first messages (a volatile topic's early ones are lost to
    a subscriber that matches later).
    """
    node = NodeProcess(*params, namespace=namespace, argv=argv)
    try:
        yield node
    except BaseException:
        node.kill()
        raise
    code, _, err = node.interrupt()
    assert code == 0 and 'Traceback' not in err, stderr_excerpt(err)


@contextlib.contextmanager
def node_with_client(*params: str, namespace: str, argv: list[str] | None = None):
    """Return a node (as :func:`running_node`) and a client; neither outlives the test."""
    with running_node(*params, namespace=namespace, argv=argv) as node:
        client = Client(f'{namespace}_client')
        try:
            yield node, client
        finally:
            client.close()


@contextlib.contextmanager
def node_in_process(namespace: str, parameters: list[Parameter] | None = None):
    """
    Yield a ``ModalSpringNode`` run in this process, spun as ``modal_spring_node`` spins it.

    Its own context, two executor threads; stopped and destroyed after.
    """
    context = Context()
    rclpy.init(context=context, domain_id=DOMAIN_ID)
    stop = StopSignals()                # not installed: this process's signals stay pytest's
    node = ModalSpringNode(stop=stop, context=context, namespace=namespace,
                           parameter_overrides=parameters or [])
    executor = PooledExecutor(2, context=context)
    executor.add_node(node)
    thread = threading.Thread(target=spin_until_stopped, args=(executor, stop), daemon=True)
    thread.start()
    try:
        yield node
    finally:
        stop.requested.set()
        thread.join(10.0)
        node.stop()
        node.destroy_node()
        end_ros(context)


#: a tool's main run with Ctrl-C pressed inside one of its calls, the interrupt landing in a
#: call into rclpy's C++ (Python's own exception swallowed, as it is raised only once such a
#: call returns); argv: the module, its function to hook, the tool's module, its command line
_INTERRUPTED_INSIDE = """
import importlib, os, signal, sys, time
module = importlib.import_module(sys.argv[1])
original = getattr(module, sys.argv[2])


def hooked(*args, **kwargs):
    try:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.01)
    except KeyboardInterrupt:
        pass
    return original(*args, **kwargs)


setattr(module, sys.argv[2], hooked)
sys.exit(importlib.import_module(sys.argv[3]).main(sys.argv[4:]))
"""


def interrupted_inside(module: str, function: str, tool: str,
                       *argv: str) -> subprocess.CompletedProcess:
    """
    Run ``tool``'s main on ``argv``, Ctrl-C pressed as it calls ``module.function``; its result.

    The moment rclpy's own signal handler shut ROS down under a publisher or subscription
    being made, deterministically: the signal arrives, and Python's exception for it is
    swallowed as a call into C++ would delay it.
    """
    return subprocess.run([sys.executable, '-c', _INTERRUPTED_INSIDE, module, function, tool,
                           *argv], capture_output=True, text=True, timeout=60)
