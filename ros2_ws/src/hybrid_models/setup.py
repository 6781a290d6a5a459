"""Install the hybrid_models ament_python package."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'hybrid_models'

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
    description='Hybrid physics + LSTM models, baselines and training (no ROS).',
    license='Apache-2.0',
    entry_points={'console_scripts': [
        'train = hybrid_models.cli.train:main',
        'evaluate = hybrid_models.cli.evaluate:main',
        'set_threshold = hybrid_models.cli.set_threshold:main',
        'set_bands = hybrid_models.cli.set_bands:main',
        'set_novelty = hybrid_models.cli.set_novelty:main',
        'reproduce_table2 = hybrid_models.cli.reproduce_table2:main',
        'reproduce_table3 = hybrid_models.cli.reproduce_table3:main',
        'compare_physics = hybrid_models.cli.compare_physics:main',
        'model_card = hybrid_models.cli.model_card:main',
        'crossval = hybrid_models.cli.crossval:main',
        'ensemble = hybrid_models.cli.ensemble:main',
        'peer_benchmark = hybrid_models.cli.peers:main',
    ]},
)
