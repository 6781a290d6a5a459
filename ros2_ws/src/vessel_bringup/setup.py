"""Install the vessel_bringup ament_python package (launch files only)."""
from glob import glob

from setuptools import setup

PACKAGE = 'vessel_bringup'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=[],
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/launch', glob('launch/*.launch.py')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='hybrid-ship maintainers',
    maintainer_email='maintainers@hybrid-ship.dev',
    description='Launch files that bring up the simulator, the predictor and a recorder.',
    license='Apache-2.0',
)
