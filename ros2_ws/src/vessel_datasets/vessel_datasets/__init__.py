"""ROS-free dataset format shared by simulation and bag conversion, and the converter."""
