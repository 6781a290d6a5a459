"""Install the vessel_description ament_python package."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'vessel_description'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/vessels', glob('vessels/*.yaml')),
    ],
    install_requires=['setuptools', 'pyyaml'],
    zip_safe=True,
    maintainer='hybrid-ship maintainers',
    maintainer_email='maintainers@hybrid-ship.dev',
    description='Vessel description files: the one source of state/control vectors (no ROS).',
    license='Apache-2.0',
    entry_points={'console_scripts': []},
)
