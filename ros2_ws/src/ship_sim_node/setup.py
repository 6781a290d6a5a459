"""Install the ship_sim_node ament_python package."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'ship_sim_node'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml') + glob('config/*.xml')),
        ('share/' + PACKAGE + '/launch', glob('launch/*.launch.py')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='hybrid-ship maintainers',
    maintainer_email='maintainers@hybrid-ship.dev',
    description='ROS 2 node simulating a vessel of any physics family (patrol boat by default).',
    license='Apache-2.0',
    entry_points={'console_scripts': ['simulator = ship_sim_node.start:main']},
)
