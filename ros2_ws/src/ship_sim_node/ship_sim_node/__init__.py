"""ROS 2 adapter around the patrol-vessel simulator: publishes state, actuators, wind."""
