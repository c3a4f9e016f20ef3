"""
How the node's frames are handed to the middleware: never in the stepping thread's way.

rclpy calls the middleware's ``publish`` holding the interpreter lock, and rmw_fastrtps (ROS 2's
default RMW) publishes synchronously unless told otherwise: the frame is sent inside ``publish``,
so whatever the transport waits for there (room in a reader's shared-memory port, a reader
process that is not scheduled) is a wait of every thread of the node. Measured on 2 cores with
three busy processes beside a 10,000-particle stream and one subscriber, ``publish`` held the
node for 0.1-2.1 s in 5 of 15 runs, and never with asynchronous publication (Fast DDS's own
thread sends the queued frame; 0 of 14 runs).

So the programs that stream clouds (the node, the replay) ask Fast DDS for asynchronous
publication, unless the user chose a mode (``RMW_FASTRTPS_PUBLICATION_MODE`` set, or an XML
profile with ``RMW_FASTRTPS_USE_QOS_FROM_XML``). Other middlewares ignore the variable. It
must be set before ``rclpy.init``, which creates the middleware's participant.
"""
from __future__ import annotations

import os
from typing import MutableMapping

#: rmw_fastrtps's choice of publication mode (ASYNCHRONOUS, SYNCHRONOUS or AUTO)
MODE_VARIABLE = 'RMW_FASTRTPS_PUBLICATION_MODE'
#: set to 1 by users whose Fast DDS XML profile holds the QoS (its publish mode included)
QOS_FROM_XML_VARIABLE = 'RMW_FASTRTPS_USE_QOS_FROM_XML'
ASYNCHRONOUS = 'ASYNCHRONOUS'


def prefer_asynchronous_publication(environ: MutableMapping[str, str] | None = None) -> str:
    """
    Ask rmw_fastrtps for asynchronous publication unless the user chose; return the mode asked.

    Returns the mode in ``environ`` afterwards ('' when an XML profile decides). ``environ`` is
    the process environment by default (read by the middleware at ``rclpy.init``).
    """
    environ = os.environ if environ is None else environ
    if environ.get(QOS_FROM_XML_VARIABLE, '') == '1':
        return environ.get(MODE_VARIABLE, '')
    if not environ.get(MODE_VARIABLE):
        environ[MODE_VARIABLE] = ASYNCHRONOUS
    return environ[MODE_VARIABLE]
