"""Install the vessel_datasets ament_python package."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'vessel_datasets'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='hybrid-ship maintainers',
    maintainer_email='maintainers@hybrid-ship.dev',
    description='Dataset format and rosbag2/MCAP conversion (no ROS).',
    license='Apache-2.0',
    entry_points={'console_scripts': [
        'simulate = vessel_datasets.simulate:main',
        'bag_to_dataset = vessel_datasets.bag_to_dataset:main',
        'table_to_dataset = vessel_datasets.table_to_dataset:main',
        'log_to_dataset = vessel_datasets.log_to_dataset:main',
    ]},
)
