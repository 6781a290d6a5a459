"""Install the vessel_diagnosis ament_python package."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'vessel_diagnosis'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
        ('share/' + PACKAGE + '/config/families', glob('config/families/*.yaml')),
    ],
    install_requires=['setuptools', 'numpy', 'scipy', 'pandas', 'pyyaml', 'matplotlib',
                      'scikit-learn'],
    zip_safe=True,
    maintainer='hybrid-ship maintainers',
    maintainer_email='maintainers@hybrid-ship.dev',
    description='Diagnosis of simulation-to-reality mismatch: locate, name, model, show (no ROS).',
    license='Apache-2.0',
    entry_points={'console_scripts': [
        'diagnose = vessel_diagnosis.cli:main',
        'simulate_scenario = vessel_diagnosis.cli_scenario:main',
        'workflow = vessel_diagnosis.cli_workflow:main',
    ]},
)
