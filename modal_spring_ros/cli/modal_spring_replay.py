"""``modal_spring_replay``: play a bag back on its topics, or re-simulate it into a new bag.

    modal_spring_replay BAG [--rate R] [--loop] [--topics T ...] [--wait-for-subscribers]
    modal_spring_replay BAG --resimulate OUT

Playback publishes each message exactly as recorded (raw CDR) with its original timing
(log times, scaled by ``--rate``) and the QoS its publishers offered.
"""
from __future__ import annotations

import argparse
import signal
import sys
import time

import rclpy
from rclpy.executors import ExternalShutdownException

from modal_spring_ros.bags.qos import playback_profile, profiles_from_yaml
from modal_spring_ros.bags.reader import BagReader, message_class
from modal_spring_ros.bags.writer import BagError
from modal_spring_ros.cli.common import fail, run_main, split_ros_args
from modal_spring_ros.ros.resimulate import resimulate

PROG = "modal_spring_replay"


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0].split(": ")[1])
    p.add_argument("bag", help="bag folder or .mcap file")
    p.add_argument("--rate", type=float, default=1.0, help="playback speed factor")
    p.add_argument("--loop", action="store_true", help="play again from the start")
    p.add_argument("--topics", nargs="+", default=None, help="only these topics")
    p.add_argument("--wait-for-subscribers", action="store_true",
                   help="start only when every topic has a subscriber (up to 30 s)")
    p.add_argument("--resimulate", metavar="OUT", default=None,
                   help="re-run the recorded simulation and write it to the new bag OUT")
    return p


def main(argv: list[str] | None = None) -> int:
    own, ros_args = split_ros_args(argv)
    args = build_parser().parse_args(own)
    args.ros_args = ros_args
    if not args.rate > 0:
        fail(PROG, f"--rate ({args.rate}) must be positive")

    def body() -> int:
        if args.resimulate:
            count = resimulate(args.bag, args.resimulate)
            print(f"re-simulated {count} frames into {args.resimulate}")
            return 0
        return play(BagReader(args.bag), args)

    try:
        return run_main(PROG, body)
    except BagError as exc:  # (a ValueError too, but keep the message first-class)
        fail(PROG, str(exc))


def play(bag: BagReader, args) -> int:

    topics = args.topics or sorted(bag.topics)
    missing = [t for t in topics if t not in bag.topics]
    if missing:
        raise BagError(f"{bag.path}: no topic {', '.join(missing)} "
                       f"(topics: {', '.join(sorted(bag.topics))})")
    signal.signal(signal.SIGTERM, lambda *_: None)
    rclpy.init(args=[PROG] + args.ros_args)
    node = rclpy.create_node("modal_spring_replay")
    try:
        publishers = {}
        for t in topics:
            info = bag.topics[t]
            try:
                cls = message_class(info.type)
            except BagError as exc:
                node.get_logger().warning(f"skipping {t}: {exc}")
                continue
            qos = playback_profile(profiles_from_yaml(info.offered_qos_profiles))
            publishers[t] = node.create_publisher(cls, t, qos)
        if args.wait_for_subscribers:
            end = time.monotonic() + 30.0
            while (time.monotonic() < end and
                   any(p.get_subscription_count() == 0 for p in publishers.values())):
                time.sleep(0.05)
            time.sleep(0.5)  # the subscribers' side of discovery completes too
        count = 0
        while True:
            start_wall = time.monotonic()
            first = None
            for m in bag.messages(list(publishers)):
                first = m.log_time_ns if first is None else first
                due = start_wall + (m.log_time_ns - first) * 1e-9 / args.rate
                delay = due - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
                if not rclpy.ok():
                    return 0
                publishers[m.topic].publish(m.data)
                count += 1
            if not args.loop:
                break
        time.sleep(0.2)  # let the last messages leave
        print(f"played {count} messages")
        return 0
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
