"""Install the hybrid_predictor ament_python package."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'hybrid_predictor'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml') + glob('config/*.xml')),
        ('share/' + PACKAGE + '/launch', glob('launch/*.launch.py')),
        ('share/' + PACKAGE + '/models/default', glob('models/default/*')),
        ('share/' + PACKAGE + '/models/crazyflie_brushless',
         glob('models/crazyflie_brushless/*')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='hybrid-ship maintainers',
    maintainer_email='maintainers@hybrid-ship.dev',
    description='ROS 2 node serving hybrid ship-motion forecasts.',
    license='Apache-2.0',
    entry_points={'console_scripts': [
        'predictor = hybrid_predictor.start:main',
        're_forecast = hybrid_predictor.bag_re_forecast:main',
    ]},
)
