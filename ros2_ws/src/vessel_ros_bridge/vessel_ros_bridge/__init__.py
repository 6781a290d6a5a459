"""Conversions between vessel arrays and ROS messages, shared by the vessel nodes."""
