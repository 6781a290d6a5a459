"""
ROS-free 4-DOF patrol-vessel physics.

Named force terms, environment (wind, waves, current), a human-like operator and a
vectorized simulator; shared by the simulator, the models and the diagnosis tool.
"""
