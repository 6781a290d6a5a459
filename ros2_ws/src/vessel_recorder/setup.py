"""Install the vessel_recorder ament_python package."""
from setuptools import find_packages, setup

PACKAGE = 'vessel_recorder'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='hybrid-ship maintainers',
    maintainer_email='maintainers@hybrid-ship.dev',
    description='ROS 2 node that records topics into rosbag2 MCAP directories.',
    license='Apache-2.0',
    entry_points={'console_scripts': ['record = vessel_recorder.recorder:main']},
)
