"""
``modal_spring_replay``: play a bag back on its topics, or re-simulate it into a new bag.

    modal_spring_replay BAG [--rate R] [--loop] [--topics T ...] [--wait-for-subscribers [TOPIC]]
    modal_spring_replay BAG --resimulate OUT

Playback publishes each message exactly as recorded (raw CDR) with its original timing
(log times, scaled by ``--rate``) and the QoS its publishers offered.
"""
from __future__ import annotations

import argparse
import sys

from modal_spring_ros.bags.files.reader import BagReader
from modal_spring_ros.bags.files.writer import BagError
from modal_spring_ros.cli.common import fail, run_main, script_parser, split_ros_args
from modal_spring_ros.ros.tools.player import play
from modal_spring_ros.ros.tools.resimulate import resimulate

PROG = 'modal_spring_replay'


def build_parser() -> argparse.ArgumentParser:
    p = script_parser(PROG, __doc__)
    p.add_argument('bag', help='bag folder or .mcap file')
    p.add_argument('--rate', type=float, default=1.0, help='playback speed factor')
    p.add_argument('--loop', action='store_true', help='play again from the start')
    p.add_argument('--topics', nargs='+', default=None, help='only these topics')
    p.add_argument('--wait-for-subscribers', nargs='?', const='', default=None,
                   metavar='TOPIC',
                   help="start only when TOPIC has a subscriber, or without TOPIC the bag's "
                        'clouds (every topic where it has none); up to 30 s')
    p.add_argument('--resimulate', metavar='OUT', default=None,
                   help='re-run the recorded simulation and write it to the new bag OUT')
    return p


def main(argv: list[str] | None = None) -> int:
    own, ros_args = split_ros_args(argv)
    args = build_parser().parse_args(own)
    args.ros_args = ros_args
    if not args.rate > 0:
        fail(PROG, f'--rate ({args.rate}) must be positive')

    def body() -> int:
        if args.resimulate:
            count = resimulate(args.bag, args.resimulate)
            print(f're-simulated {count} frames into {args.resimulate}')
            return 0
        bag = BagReader(args.bag)
        if not bag.finalised:
            print(f'{PROG}: note: {args.bag} was not closed by its writer (killed?): it is read '
                  f'to its last complete chunk; modal_spring_reindex {args.bag} makes it whole '
                  'for every reader', file=sys.stderr)
        played = play(bag, args.topics, args.rate, args.loop, args.wait_for_subscribers,
                      [PROG] + args.ros_args)
        print(f'played {played} messages')
        return 0

    try:
        return run_main(PROG, body)
    except BagError as exc:  # (a ValueError too, but keep the message first-class)
        fail(PROG, str(exc))


if __name__ == '__main__':
    sys.exit(main())
