"""``wallbot-sim bag reindex BAG``: bag maintenance."""

from __future__ import annotations

import argparse

HELP = 'bag maintenance: reindex (repair a bag whose recording was killed)'


def add_arguments(parser: argparse.ArgumentParser) -> None:
    actions = parser.add_subparsers(dest='action', metavar='ACTION', parser_class=type(parser))
    actions.required = True
    reindex = actions.add_parser('reindex', help='rebuild index, summary and metadata.yaml from the MCAP data',
                                 description='Rebuild a bag (in place) from its MCAP data: use it after the '
                                             'recorder was killed (SIGKILL, power loss).')
    reindex.add_argument('bag', metavar='BAG', help='bag directory')


def main(args: argparse.Namespace) -> int:
    from wallbot_sim.bag.reindex import reindex
    report = reindex(args.bag)
    note = ' (the end was cut: its last partial chunk is dropped)' if report.truncated else ''
    print(f'reindexed {report.path}: {report.messages} messages, {report.duration:.3f} s, '
          f'{report.chunks} chunks{note}; {", ".join(report.replaced)} replaced by {", ".join(report.written)}')
    return 0
