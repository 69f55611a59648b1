"""ament_python build of bb_friction_ros (colcon build, or pip install -e . in .venv)."""

from glob import glob

from setuptools import find_packages, setup

package_name = 'bb_friction_ros'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', sorted(glob('config/*.yaml'))),
        ('share/' + package_name + '/config/sweeps', sorted(glob('config/sweeps/*.yaml'))),
        ('share/' + package_name + '/config/servo', sorted(glob('config/servo/*.yaml'))),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='bb_friction_ros maintainers',
    maintainer_email='maintainers@users.noreply.h-seed-0c5ad298.example',
    description='Ball-screw friction prediction with ball-to-ball contact friction.',
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'bb-friction = bb_friction_ros.cli:main',
            'friction_node = bb_friction_ros.node_entry:main',
        ],
        # the friction_node fixture for launch-free tests (bb_friction_ros/pytest_plugin.py)
        'pytest11': ['bb_friction_ros = bb_friction_ros.pytest_plugin'],
    },
)
