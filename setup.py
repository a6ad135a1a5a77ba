"""ament_python package definition for crawler_sim."""
from glob import glob
import os

from setuptools import Extension, find_packages, setup

package_name = 'crawler_sim'


def compiled_core() -> list[Extension]:
    """The compiled solvers and the actuator's tick (Cython sources, cythonized and compiled by
    setuptools' build_ext at install time: ``pip install``, ``colcon build``), so nothing
    compiles on first use."""
    # IEEE arithmetic as written: no fused multiply-add (bit-identical runs across builds)
    flags = ['-O2', '-ffp-contract=off']
    return [Extension(f'crawler_sim.core.solvers.{n}', [f'crawler_sim/core/solvers/{n}.pyx'],
                      extra_compile_args=flags) for n in ('_gait', '_exact', '_stepping')] + [
        # the actuator's per-tick work (core/actuator.py is its Python side)
        Extension('crawler_sim.core._actuator', ['crawler_sim/core/_actuator.pyx'],
                  extra_compile_args=flags),
        # the plant's compiled step (core/plant/engine.py's run to the publish grid, one or N
        # crawlers: the vector environment's step)
        Extension('crawler_sim.core.plant._batch', ['crawler_sim/core/plant/_batch.pyx'],
                  extra_compile_args=flags),
        # the environments' step over N rows (envs/plant.py, envs/vector.py)
        Extension('crawler_sim.envs._rows', ['crawler_sim/envs/_rows.pyx'],
                  extra_compile_args=flags)]


setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*', 'benchmarks', 'benchmarks.*']),
    # sim_node's Fast DDS profile, read at run time next to its module (ros/sim/main.py)
    package_data={'crawler_sim.ros.sim': ['fastdds_profile.xml']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        # ROS parameter files and scene files in separate folders (neither is mistaken for
        # the other); the launch file, and the RViz and Foxglove layouts of the markers
        (os.path.join('share', package_name, 'config', 'ros'), glob('config/ros/*.yaml')),
        (os.path.join('share', package_name, 'config', 'scenes'), glob('config/scenes/*.yaml')),
        (os.path.join('share', package_name, 'config', 'viz'), glob('config/viz/*')),
        (os.path.join('share', package_name, 'launch'), glob('launch/*.launch.py')),
        # `crawler-sim` on PATH after `source install/setup.bash` (colcon puts <prefix>/bin on
        # PATH; the console scripts below go to lib/crawler_sim/ for `ros2 run`)
        ('bin', ['scripts/crawler-sim']),
        (os.path.join('share', package_name, 'config', 'sweeps'), glob('config/sweeps/*.yaml')),
    ],
    # What the package imports (checked by test/test_packaging.py). ROS 2 itself (rclpy and
    # the message packages) comes from a Jazzy install, or from the ros-jazzy-* wheels: the
    # `ros` extra. colcon reads package.xml instead.
    install_requires=['numpy>=1.26', 'scipy>=1.11', 'PyYAML>=6', 'mcap>=1.6,<2',
                      'zstandard>=0.19', 'lz4>=4', 'matplotlib>=3.8', 'rosbags>=0.11.9',
                      'gymnasium>=1.0'],
    extras_require={
        'ros': ['ros-jazzy-rclpy[fastrtps]>=7.1,<8', 'ros-jazzy-common-interfaces>=5.3,<6'],
        'sweep': ['pandas>=2.2', 'pyarrow>=15', 'dask[distributed]>=2024.1'],
        'bench': ['gymnasium[mujoco]>=1.0'],     # benchmarks/gym_speed.py: MuJoCo Swimmer-v5
        # the test and lint tools (with `sweep`, what `make test` adds: requirements-test.txt)
        'test': ['pytest>=8', 'hypothesis>=6.100', 'mcap-ros2-support>=0.6,<1',
                 'yourdfpy>=0.0.60'],
        'lint': ['ruff>=0.6'],
    },
    ext_modules=compiled_core(),
    zip_safe=False,
    maintainer='crawler_sim developers',
    maintainer_email='dev@crawler-sim.invalid',
    description='Exact simulation of friction-based crawling locomotion as a ROS 2 node.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'sim_node = crawler_sim.ros.sim_node:main',
            'gait_node = crawler_sim.ros.gait_node:main',
            'replay_node = crawler_sim.ros.replay_node:main',
            'crawler-sim = crawler_sim.cli:main',
        ],
    },
)
