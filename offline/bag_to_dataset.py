#!/usr/bin/env python3
"""
Convert rosbag2 recordings (MCAP, also damaged ones) into a training dataset.

    python offline/bag_to_dataset.py BAG... --vessel VESSEL --out DATASET

The ``bag_to_dataset`` program of vessel_datasets (``--help`` for the options, the topic
map and the exit codes); ``ros2 run vessel_datasets bag_to_dataset`` is the same program
installed.
"""

import sys

from vessel_datasets.bag_to_dataset import main

if __name__ == '__main__':
    sys.exit(main())
