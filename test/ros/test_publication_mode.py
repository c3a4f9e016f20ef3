"""The programs that stream clouds ask Fast DDS for asynchronous publication, unless told."""
from __future__ import annotations

import os
import subprocess
import sys

from modal_spring_ros.ros.stream.publication_mode import (ASYNCHRONOUS, MODE_VARIABLE,
                                                          prefer_asynchronous_publication,
                                                          QOS_FROM_XML_VARIABLE)
import pytest


def test_asynchronous_unless_the_user_chose():
    environ: dict[str, str] = {}
    assert prefer_asynchronous_publication(environ) == ASYNCHRONOUS
    assert environ == {MODE_VARIABLE: ASYNCHRONOUS}
    assert prefer_asynchronous_publication({MODE_VARIABLE: ''}) == ASYNCHRONOUS


@pytest.mark.parametrize('mode', ['SYNCHRONOUS', 'AUTO'])
def test_a_mode_the_user_set_is_kept(mode):
    environ = {MODE_VARIABLE: mode}
    assert prefer_asynchronous_publication(environ) == mode
    assert environ == {MODE_VARIABLE: mode}


def test_an_xml_profile_that_holds_the_qos_decides():
    environ = {QOS_FROM_XML_VARIABLE: '1'}
    assert prefer_asynchronous_publication(environ) == ''
    assert environ == {QOS_FROM_XML_VARIABLE: '1'}


# Stops the program at rclpy.init, printing the mode the middleware would read there.
AT_INIT = """
import os, sys, rclpy
def init(*args, **kwargs):
    print('mode at init:', os.environ.get({variable!r}, ''))
    sys.exit(0)
rclpy.init = init
{call}
"""


@pytest.mark.parametrize('call', [
    'from modal_spring_ros.cli.modal_spring_node import main; main([])',
    'from modal_spring_ros.ros.tools.player import play; from unittest import mock; '
    'bag = mock.MagicMock(topics={"/points": mock.MagicMock(type_name="sensor_msgs/msg/Point'
    'Cloud2")}); play(bag, ["/points"])'])
@pytest.mark.parametrize('given, expected', [(None, ASYNCHRONOUS), ('SYNCHRONOUS', 'SYNCHRONOUS')])
def test_the_node_and_the_replay_set_it_before_rclpy_init(call, given, expected):
    env = {k: v for k, v in os.environ.items() if k not in (MODE_VARIABLE, QOS_FROM_XML_VARIABLE)}
    if given:
        env[MODE_VARIABLE] = given
    done = subprocess.run([sys.executable, '-c', AT_INIT.format(variable=MODE_VARIABLE,
                                                                call=call)],
                          capture_output=True, text=True, env=env, timeout=60)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().splitlines()[-1] == f'mode at init: {expected}', done.stdout
