"""ament_python packaging, as `ros2 pkg create --build-type ament_python` makes it."""
from glob import glob
import os

from setuptools import find_packages, setup

package_name = 'sensorispace_ros'


def files(pattern):
    # glob() of an empty dir is [], which setuptools accepts; skip sub-dirs
    # and dotfiles (.gitkeep) so only real data is installed.
    return [p for p in sorted(glob(pattern)) if os.path.isfile(p)]


setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['tests', 'tests.*']),
    # The table of every parameter, read by sensorispace_ros/config.py.
    package_data={package_name: ['parameters.yaml']},
    data_files=[
        ('share/ament_index/resource_index/packages',
            ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', files('config/*.yaml')),
        ('share/' + package_name + '/msg_schemas', files('msg_schemas/*')),
        ('share/' + package_name + '/launch', files('launch/*')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='sensorispace_ros maintainers',
    maintainer_email='sensorispace-ros-maintainers@users.noreply.github.com',
    description='sensorispace_ros: ROS 2 nodes, offline pipeline and bag tools',
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'sensorispace = sensorispace_ros.cli.main:main',
            'environment = sensorispace_ros.graph.nodes.environment:main',
            'body = sensorispace_ros.graph.nodes.body:main',
            'agent = sensorispace_ros.graph.nodes.agent:main',
            'representation = sensorispace_ros.graph.nodes.representation:main',
            'recorder = sensorispace_ros.graph.nodes.recorder:main',
            'replay = sensorispace_ros.graph.nodes.replay:main',
            'viewer = sensorispace_ros.graph.nodes.viewer:main',
        ],
    },
)
