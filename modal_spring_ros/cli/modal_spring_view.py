"""
``modal_spring_view``: see the stream in Foxglove, with nothing else installed.

    modal_spring_view [--start-node] [--host H] [--port P] [--max-rate-hz R] [--ros-args ...]

Serves ``points``, ``mesh``, ``/diagnostics``, ``/tf`` and ``/tf_static`` of the graph on a
Foxglove WebSocket server (``ws://127.0.0.1:8765`` by default): open it in Foxglove (the app at
app.foxglove.dev or the desktop app: "Open connection", "Foxglove WebSocket") and add a 3D
panel. ``--start-node`` also starts ``modal_spring_node`` (given the same ``--ros-args``, and
stopped on exit); a namespace given with ``-r __ns:=/x`` is the node's and the view's.
"""
from __future__ import annotations

import argparse
import math
import sys

from modal_spring_ros.cli.common import EXIT_USAGE, script_parser, split_ros_args
from modal_spring_ros.ros.process.companion_node import start_companion, stop_companion
from modal_spring_ros.ros.process.stop_signals import (end_ros, init_ros, spin_until_stopped,
                                                       StopSignals)
from modal_spring_ros.ros.tools.live_view import (DEFAULT_MAX_RATE_HZ, DEFAULT_PORT, foxglove,
                                                  LiveView, SDK_MISSING, ServeError)
from modal_spring_ros.scenes.resources import executable
import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

PROG = 'modal_spring_view'


def parser() -> argparse.ArgumentParser:
    p = script_parser(PROG, __doc__)
    p.add_argument('--start-node', action='store_true',
                   help='also start modal_spring_node (with the same --ros-args; stopped on '
                        'exit)')
    p.add_argument('--host', default='127.0.0.1',
                   help='address to serve on (default 127.0.0.1: this machine only; 0.0.0.0 '
                        'for every interface)')
    p.add_argument('--port', type=int, default=DEFAULT_PORT,
                   help=f'WebSocket port (default {DEFAULT_PORT}; 0: any free one)')
    p.add_argument('--max-rate-hz', type=float, default=DEFAULT_MAX_RATE_HZ,
                   help=f'most clouds a second sent to the view (default '
                        f'{DEFAULT_MAX_RATE_HZ:g})')
    return p


def check(args: argparse.Namespace) -> str | None:
    """Return what is wrong with the options, or None."""
    if not 0 <= args.port <= 65535:
        return f'--port ({args.port}) must be from 0 to 65535'
    if not (math.isfinite(args.max_rate_hz) and 0.0 < args.max_rate_hz <= 1000.0):
        return f'--max-rate-hz ({args.max_rate_hz}) must be above 0 and at most 1000'
    if foxglove is None:
        return SDK_MISSING
    return None


def main(argv: list[str] | None = None) -> int:
    own, ros_args = split_ros_args(argv)
    args = parser().parse_args(own)
    problem = check(args)
    if problem:
        print(f'{PROG}: error: {problem}', file=sys.stderr)
        return EXIT_USAGE
    stop = StopSignals().install()      # Ctrl-C while it starts: out at once, no traceback
    init_ros([sys.argv[0], *ros_args] if ros_args else None)
    node_process = None
    node = view = None
    try:
        executor = SingleThreadedExecutor()
        node = rclpy.create_node('modal_spring_view', start_parameter_services=False)
        try:
            view = LiveView(node, args.host, args.port, args.max_rate_hz)
        except ServeError as exc:
            print(f'{PROG}: error: --host {args.host} --port {args.port}: {exc}',
                  file=sys.stderr)
            return EXIT_USAGE
        if args.start_node:
            node_process = start_companion([str(executable('modal_spring_node')), *ros_args])
        print(f'[{PROG}] serving {node.resolve_topic_name("points")} and the rest on '
              f'ws://{args.host}:{view.port} (Foxglove: Open connection)', file=sys.stderr,
              flush=True)
        executor.add_node(node)
        stop.interrupting = False       # serving: a signal ends the spin loop, then the view
        spin_until_stopped(executor, stop)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if view is not None:
            view.stop()
        if node is not None:
            node.destroy_node()
        end_ros()
        stop_companion(node_process)
    return 0


if __name__ == '__main__':
    sys.exit(main())
