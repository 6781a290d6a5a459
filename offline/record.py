#!/usr/bin/env python3
"""
Record ROS 2 topics into a rosbag2 MCAP directory: `ros2 run vessel_recorder record`.

The recorder is the ROS package vessel_recorder; this entry point runs it from the
repository (`python offline/record.py --help` for its options).
"""

import sys

from vessel_recorder.recorder import main

if __name__ == '__main__':
    sys.exit(main())
