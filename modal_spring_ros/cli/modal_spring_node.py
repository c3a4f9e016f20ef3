"""
``modal_spring_node``: stream a scene's filtered deformation into the ROS graph.

    modal_spring_node [-h] [--managed] [--ros-args -p NAME:=VALUE ... --params-file FILE ...]

``--managed`` runs it as a lifecycle node (:mod:`~modal_spring_ros.ros.managed_node`). Every
setting is a ROS parameter (listed by ``--help``); change them at runtime with
``ros2 param set`` or any ``SetParameters`` client.
"""
from __future__ import annotations

import sys

from modal_spring_ros.bags.files.writer import BagError
from modal_spring_ros.cli.common import EXIT_USAGE, split_ros_args
from modal_spring_ros.core.model.scene import SceneError
from modal_spring_ros.core.worker import WorkerError
from modal_spring_ros.ros.managed_node import ManagedModalSpringNode
from modal_spring_ros.ros.node import ModalSpringNode
from modal_spring_ros.ros.parameters import PARAMETERS
from modal_spring_ros.ros.process.interpreter_switching import switch_threads_often
from modal_spring_ros.ros.process.pooled_executor import PooledExecutor
from modal_spring_ros.ros.process.shared_memory import (POINT_BYTES, prefer_large_shared_memory,
                                                        scene_argument)
from modal_spring_ros.ros.process.stop_signals import (end_ros, init_ros, spin_until_stopped,
                                                       StopSignals)
from modal_spring_ros.ros.stream.publication_mode import prefer_asynchronous_publication
from modal_spring_ros.scenes.files.declared_size import declared_particles
from modal_spring_ros.scenes.resources import share_directory
import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException

PROG = 'modal_spring_node'
#: executor threads: the parameter services, and the node's own services beside them
EXECUTOR_THREADS = 2


USAGE = """usage: modal_spring_node [-h] [--managed]
                         [--ros-args -p NAME:=VALUE ... --params-file FILE ...]

Steps a mass-spring scene in modal coordinates and streams it as sensor_msgs/PointCloud2 on
'points', with /diagnostics. Every setting is a ROS parameter: give it at start with
--ros-args -p NAME:=VALUE (or a parameter file), change it at runtime with ros2 param set or
SetParameters(Atomically). Services: ~/reset (std_srvs/Trigger), ~/pause (std_srvs/SetBool),
~/step (std_srvs/Trigger: one frame, while paused).
--managed: a lifecycle node, created unconfigured (configure loads the scene and computes the
modes, activate streams, deactivate stops the frames, cleanup frees; lifecycle_msgs services
~/change_state, ~/get_state).

parameters (read-only ones only at start):"""


def usage() -> str:
    """Return the command line and every parameter with its default and description."""
    lines = [USAGE]
    for name, (default, descriptor) in PARAMETERS.items():
        flag = ', read-only' if descriptor.read_only else ''
        lines.append(f'  {name} (default {default!r}{flag})')
        lines.append(f'      {descriptor.description}')
    return '\n'.join(lines)


def main(args: list[str] | None = None) -> int:
    own, ros_args = split_ros_args(args)
    if own and own[0] in ('-h', '--help'):
        print(usage())
        return 0
    if own not in ([], ['--managed']):
        print(f'{PROG}: error: unknown arguments {own} (settings are ROS parameters: '
              f'--ros-args -p NAME:=VALUE)', file=sys.stderr)
        return EXIT_USAGE
    kind = ManagedModalSpringNode if own else ModalSpringNode
    stop = StopSignals().install()  # ROS is shut down last, once the node's threads are joined
    prefer_asynchronous_publication()  # a frame's sending never holds the stepping thread
    switch_threads_often()    # a flood of inputs on another thread never starves the stream
    # large clouds fit Fast DDS's shared-memory segment
    scene = scene_argument(ros_args, PARAMETERS['scene'][0])
    particles = declared_particles(scene)
    prefer_large_shared_memory(share_directory(),
                               None if particles is None else particles * POINT_BYTES)
    init_ros(args)
    node = None
    try:
        # the executor before the node: once the node is seen in the graph, a Ctrl-C can no
        # longer land inside the executor's constructor (which leaves a half-built executor
        # whose finaliser prints a traceback)
        executor = PooledExecutor(EXECUTOR_THREADS, name='modal_spring_executor')
        node = kind(stop=stop)
        executor.add_node(node)
        stop.interrupting = False       # streaming: a signal ends the spin loop, then the node
        spin_until_stopped(executor, stop)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (SceneError, ValueError, ParameterException, BagError) as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return EXIT_USAGE
    except MemoryError as exc:   # numpy names the array it could not allocate
        print(f'{PROG}: error: not enough memory: {exc or "an allocation failed"}',
              file=sys.stderr)
        return EXIT_USAGE
    except WorkerError as exc:
        if stop.requested.is_set() or not rclpy.ok():
            return 0  # interrupted while starting (say, during a long mode computation)
        print(f'{PROG}: error: computing the modes failed: {exc}', file=sys.stderr)
        return 1
    except Exception:
        if stop.requested.is_set() or not rclpy.ok():
            return 0
        raise
    finally:
        if node is not None:
            node.stop()
            node.destroy_node()
        end_ros()
    return 0


if __name__ == '__main__':
    sys.exit(main())
