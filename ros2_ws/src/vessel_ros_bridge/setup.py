"""Install the vessel_ros_bridge ament_python package."""

from setuptools import find_packages, setup

PACKAGE = 'vessel_ros_bridge'

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
    description='Message conversions and YAML parameter specs shared by the vessel nodes.',
    license='Apache-2.0',
    entry_points={'console_scripts': []},
)
