"""Install the vessel_physics ament_python package."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'vessel_physics'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    # Isherwood (1972) wind coefficient table, read at run time by the patrol's wind loads;
    # each family's candidate library for the diagnosis.
    package_data={PACKAGE: ['patrol/data/*.csv', '*/diagnosis_candidates.yaml']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
        ('share/' + PACKAGE + '/config/simulation', glob('config/simulation/*.yaml')),
    ],
    install_requires=['setuptools', 'numpy', 'scipy', 'pyyaml', 'array-api-compat'],
    zip_safe=True,
    maintainer='hybrid-ship maintainers',
    maintainer_email='maintainers@hybrid-ship.dev',
    description='Vessel physics families (patrol, MMG, Fossen, multirotor) and their simulator '
                '(no ROS).',
    license='Apache-2.0',
    entry_points={'console_scripts': [
        'scale_physics = vessel_physics.mmg.scale:main',
    ]},
)
