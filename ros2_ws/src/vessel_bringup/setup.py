"""Install the vessel_bringup ament_python package (launch files and the demo client)."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'vessel_bringup'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/launch', glob('launch/*.launch.py')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='hybrid-ship maintainers',
    maintainer_email='maintainers@hybrid-ship.dev',
    description='Launch files that bring up the simulator, the predictor and a recorder; '
                'the demo client.',
    license='Apache-2.0',
    entry_points={'console_scripts': ['demo = vessel_bringup.demo:main']},
)
