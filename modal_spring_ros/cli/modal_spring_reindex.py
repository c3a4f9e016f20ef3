"""
``modal_spring_reindex``: make killed recordings readable by every reader, as ``ros2 bag reindex``.

    modal_spring_reindex BAG [BAG ...]

A recorder or node killed before it closed its bag (SIGKILL, a power cut) leaves an MCAP file
without its summary and a folder without ``metadata.yaml``: the project's tools read it, mcap's
and rosbags' readers do not. This writes each file again, finalised, from its complete records
(nothing decoded, nothing imported), and the folder's ``metadata.yaml``; a finalised file is
left as it is. See :mod:`modal_spring_ros.bags.files.reindex`.
"""
from __future__ import annotations

import sys

from modal_spring_ros.bags.files.reindex import reindex
from modal_spring_ros.cli.common import run_main, script_parser

PROG = 'modal_spring_reindex'


def main(argv: list[str] | None = None) -> int:
    p = script_parser(PROG, __doc__)
    p.add_argument('bags', nargs='+', metavar='BAG', help='bag folder or .mcap file')
    args = p.parse_args(argv)

    def body() -> int:
        for bag in args.bags:
            for report in reindex(bag):
                print(f'{bag}: {report.name}: {report.describe()}')
        return 0

    return run_main(PROG, body)


if __name__ == '__main__':
    sys.exit(main())
