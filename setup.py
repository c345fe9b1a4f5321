"""ament_python package: colcon installs node executables under lib/rigid_body_sim."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'rigid_body_sim'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', [f'resource/{PACKAGE}']),
        (f'share/{PACKAGE}', ['package.xml']),
        (f'share/{PACKAGE}/config', glob('config/*.yaml') + glob('config/*.json')),
        (f'share/{PACKAGE}/launch', glob('launch/*.py')),
    ],
    # Versions are pinned in requirements.txt (PyPI) or resolved by rosdep (package.xml).
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='rigid_body_sim developers',
    maintainer_email='dev@rigid-body-sim.invalid',
    description='Live spacecraft attitude simulation for ROS 2 Jazzy',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'rigid-body-sim = rigid_body_sim.cli:main',
            'simulator = rigid_body_sim.nodes.entry:simulator',
            'controller = rigid_body_sim.nodes.entry:controller',
            'recorder = rigid_body_sim.nodes.entry:recorder',
            'replay = rigid_body_sim.nodes.entry:replay',
            'viewer = rigid_body_sim.nodes.entry:viewer',
        ],
    },
)
