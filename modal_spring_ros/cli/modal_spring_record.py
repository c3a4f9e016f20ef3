"""
``modal_spring_record``: record topics into a rosbag2 MCAP bag, as ``ros2 bag record`` does.

    modal_spring_record --output DIR [--topics points sim_time applied_parameter_events mesh
                        /diagnostics /parameter_events /tf /tf_static]
                        [--node modal_spring] [--duration S]

See :mod:`modal_spring_ros.ros.tools.recorder` for what is stored and how.
"""
from __future__ import annotations

import math
import sys
import time

from modal_spring_ros.bags.files.writer import (BagError, BagWriter, check_new_bag_path,
                                                DEFAULT_CHUNK_SECONDS, DEFAULT_CHUNK_SIZE)
from modal_spring_ros.cli.common import fail, script_parser, split_ros_args
from modal_spring_ros.core.model.scene import SceneError
from modal_spring_ros.ros.process.stop_signals import end_ros, init_ros, StopSignals
from modal_spring_ros.ros.tools.recorder import DEFAULT_TOPICS, Recorder, snapshot_parameters
from modal_spring_ros.scenes.resources import load_scene
import rclpy
from rclpy.executors import ExternalShutdownException

PROG = 'modal_spring_record'


def main(argv: list[str] | None = None) -> int:
    p = script_parser(PROG, __doc__)
    p.add_argument('--output', '-o', required=True, help='new bag folder')
    p.add_argument('--topics', nargs='+', default=DEFAULT_TOPICS,
                   help=f"topics to record (default: {' '.join(DEFAULT_TOPICS)})")
    p.add_argument('--node', default='modal_spring',
                   help='the simulation node whose scene and parameters are stored')
    p.add_argument('--duration', type=float, default=None, help='stop after S seconds')
    p.add_argument('--chunk-size', type=int, default=DEFAULT_CHUNK_SIZE,
                   help=f'MCAP chunk size in bytes (default {DEFAULT_CHUNK_SIZE})')
    p.add_argument('--chunk-seconds', type=float, default=DEFAULT_CHUNK_SECONDS,
                   help=f'close a chunk when it is this old, full or not (default '
                        f'{DEFAULT_CHUNK_SECONDS:g} s): a killed recorder loses at most '
                        'about that much')
    p.add_argument('--wait-for-node', type=float, default=10.0,
                   help="seconds to wait for the node's parameters (default 10)")
    own, ros_args = split_ros_args(argv)
    args = p.parse_args(own)
    if args.duration is not None and not args.duration > 0:
        fail(PROG, f'--duration ({args.duration}) must be positive')
    if args.chunk_size < 1:
        fail(PROG, f'--chunk-size ({args.chunk_size}) must be at least 1 byte')
    if not (math.isfinite(args.chunk_seconds) and args.chunk_seconds > 0):
        fail(PROG, f'--chunk-seconds ({args.chunk_seconds}) must be a positive number')
    try:
        check_new_bag_path(args.output)
    except BagError as exc:
        fail(PROG, str(exc))

    # Ctrl-C and SIGTERM ask the recorder to stop (interrupting it until it subscribes, never
    # a write half done after); ROS stays up until it ends (never shut down under a
    # subscription being made: that failed with a traceback)
    stop = StopSignals().install()
    init_ros([PROG] + ros_args)
    try:
        node = rclpy.create_node('modal_spring_recorder')
    except BaseException:
        end_ros()
        raise
    target = node.resolve_topic_name(args.node) if not args.node.startswith('/') else args.node
    writer, error = None, ''
    try:
        writer = BagWriter(args.output, chunk_size=args.chunk_size,
                           chunk_seconds=args.chunk_seconds, attachments=True)
        # Subscribe first, then take the parameters: a change in between is then both in the
        # snapshot and on /parameter_events (harmless), never in neither.
        stop.interrupting = False
        Recorder(node, writer, args.topics, target)
        params = snapshot_parameters(node, target, args.wait_for_node, stop.requested.is_set)
        record, scene = {'source': PROG, 'node': target}, None
        if params is None:
            if not stop.requested.is_set():     # (asked to stop while it waited: no warning)
                node.get_logger().warning(f'node {target} did not answer: the bag will not '
                                          'hold its scene and parameters (no --resimulate)')
        else:
            record['parameters'] = params
            try:
                scene = load_scene(params.get('scene', ''))
            except SceneError as exc:
                node.get_logger().warning(f'scene not stored: {exc}')
            node.get_logger().info(f'stored {len(params)} parameters of node {target}'
                                   + (' and its scene' if scene is not None else ''))
        writer.add_run_record(record, scene)
        end = None if args.duration is None else time.monotonic() + args.duration
        while stop.running(node.context) and (end is None or time.monotonic() < end):
            rclpy.spin_once(node, timeout_sec=0.05)
            writer.flush_if_due()  # also when messages stop coming
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except BagError as exc:
        error = str(exc)
    finally:
        if writer is not None:
            try:
                writer.close()        # a full disk fails here too: said once, below
                print(f'wrote {args.output}: {writer.message_count} messages')
            except BagError as exc:
                error = error or str(exc)
        node.destroy_node()
        end_ros()
    if error:
        fail(PROG, f'{error} (the chunks written before stay readable)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
