"""
``modal_spring_gripper``: an example gripper that carries the sheet's clamp in a circle.

    modal_spring_gripper [--start-node] [--radius M] [--frequency-hz F] [--turn-deg D]
                         [--centre X Y Z] [--rate-hz R] [--duration S] [--ros-args ...]

Publishes ``geometry_msgs/PoseStamped`` on ``anchor_pose`` (relative: remap or use a
namespace to reach a node elsewhere): the position circles ``--centre`` in the x-z plane the
sheets hang in and the orientation turns to and fro about y (their normal), as a robot's gripper
holding the clamp would. A node
started with ``anchor.source:=topic`` follows it. ``--start-node`` also starts one (with the
default scene) and stops it on exit, so one command shows the whole thing::

    modal_spring_gripper --start-node       # then view 'points' in RViz (frame 'world')
"""
from __future__ import annotations

import argparse
import math
import subprocess
import sys
import time

from geometry_msgs.msg import PoseStamped
from modal_spring_ros.cli.common import EXIT_USAGE, script_parser, split_ros_args
from modal_spring_ros.core.motion.clamp_follower import DEFAULT_FOLLOW_HZ
from modal_spring_ros.ros.process.companion_node import start_companion, stop_companion
from modal_spring_ros.ros.process.stop_signals import end_ros, init_ros, StopSignals
from modal_spring_ros.scenes.resources import executable
import rclpy
from rclpy.executors import ExternalShutdownException

PROG = 'modal_spring_gripper'
TOPIC = 'anchor_pose'


def gripper_pose(t: float, args: argparse.Namespace) -> PoseStamped:
    """Return the gripper's pose at time ``t`` (s): on the circle, turned by the swing angle."""
    m = PoseStamped()
    m.header.frame_id = args.frame_id
    phase = 2.0 * math.pi * args.frequency_hz * t
    ramp = min(t / args.ramp_s, 1.0) if args.ramp_s > 0 else 1.0
    x, y, z = args.centre
    m.pose.position.x = x + ramp * args.radius * math.sin(phase)
    m.pose.position.y = y
    m.pose.position.z = z + ramp * args.radius * (math.cos(phase) - 1.0)
    angle = ramp * math.radians(args.turn_deg) * math.sin(phase)
    m.pose.orientation.y, m.pose.orientation.w = math.sin(angle / 2), math.cos(angle / 2)
    return m


def parser() -> argparse.ArgumentParser:
    p = script_parser(PROG, __doc__)
    p.add_argument('--start-node', action='store_true',
                   help='also start modal_spring_node following the gripper (stopped on exit)')
    p.add_argument('--radius', type=float, default=0.1, help='circle radius, m (default 0.1)')
    p.add_argument('--frequency-hz', type=float, default=0.3,
                   help='turns per second around the circle (default 0.3)')
    p.add_argument('--turn-deg', type=float, default=30.0,
                   help='how far the gripper turns to and fro about y, degrees (default 30)')
    p.add_argument('--centre', type=float, nargs=3, default=[0.45, 0.0, 0.0],
                   metavar=('X', 'Y', 'Z'),
                   help="where the circle starts from, m (default the default scene's clamp "
                        'centre, 0.45 0 0)')
    p.add_argument('--ramp-s', type=float, default=2.0,
                   help='seconds over which the motion grows from still (default 2)')
    p.add_argument('--rate-hz', type=float, default=50.0, help='poses per second (default 50)')
    p.add_argument('--duration', type=float, default=0.0,
                   help='seconds to run; 0 = until Ctrl-C (default)')
    p.add_argument('--frame-id', default='world', help='header.frame_id (default world)')
    return p


def check(args: argparse.Namespace) -> str | None:
    """Return what is wrong with the options, or None."""
    for name in ('radius', 'frequency_hz', 'turn_deg', 'ramp_s', 'duration'):
        value = getattr(args, name)
        if not (math.isfinite(value) and value >= 0.0):
            return f"--{name.replace('_', '-')} ({value}) must be finite and not negative"
    if not (math.isfinite(args.rate_hz) and 0.0 < args.rate_hz <= 1000.0):
        return f'--rate-hz ({args.rate_hz}) must be above 0 and at most 1000'
    if not all(math.isfinite(v) for v in args.centre):
        return '--centre must be three finite numbers'
    return None


def start_node(ros_args: list[str]) -> subprocess.Popen:
    command = [str(executable('modal_spring_node')), '--ros-args', '-p', 'anchor.source:=topic',
               '-p', f'anchor.follow_hz:={DEFAULT_FOLLOW_HZ}']
    extra = ros_args[1:] if ros_args else []
    return start_companion(command + extra)


def main(argv: list[str] | None = None) -> int:
    own, ros_args = split_ros_args(argv)
    args = parser().parse_args(own)
    problem = check(args)
    if problem:
        print(f'{PROG}: error: {problem}', file=sys.stderr)
        return EXIT_USAGE
    # a signal asks it to stop; ROS stays up until it has (never shut down under a publish)
    stop = StopSignals().install()
    node_process = node = None
    ros_up = False
    try:
        node_process = start_node(ros_args) if args.start_node else None
        init_ros([sys.argv[0], *ros_args] if ros_args else None)
        ros_up = True
        node = rclpy.create_node('modal_spring_gripper')
        publisher = node.create_publisher(PoseStamped, TOPIC, 10)
        print(f'[{PROG}] circling {args.radius:g} m at {args.frequency_hz:g} Hz, turning '
              f'+-{args.turn_deg:g} degrees, on {publisher.topic_name}', file=sys.stderr)
        start = time.monotonic()
        while stop.running(node.context):
            t = time.monotonic() - start
            if args.duration and t > args.duration:
                break
            publisher.publish(gripper_pose(t, args))
            time.sleep(max(0.0, start + (math.floor(t * args.rate_hz) + 1) / args.rate_hz
                           - time.monotonic()))
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        if ros_up:
            end_ros()
        stop_companion(node_process)
    return 0


if __name__ == '__main__':
    sys.exit(main())
