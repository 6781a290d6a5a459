"""Record ROS 2 topics into rosbag2 MCAP directories (``ros2 run vessel_recorder record``)."""
