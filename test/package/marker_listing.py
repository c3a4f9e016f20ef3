"""
A pytest plugin for ``test_fast_loop``: after collection, one line per test with its markers.

Loaded with ``-p marker_listing`` (its folder on ``PYTHONPATH``): ``MARKED <node id> <marks>``, the
marks ``ros``, ``slow`` and ``group:<name>`` (pytest-xdist's group) it has, comma-separated.
"""
from __future__ import annotations

#: the markers that choose a loop
LISTED = ('ros', 'slow')


def pytest_collection_finish(session):
    writer = session.config.get_terminal_writer()
    for item in session.items:
        marks = [m for m in LISTED if item.get_closest_marker(m) is not None]
        marks += [f'group:{m.args[0]}' for m in item.iter_markers('xdist_group')]
        marks = ','.join(marks)
        writer.line(f'MARKED {item.nodeid} {marks}')
