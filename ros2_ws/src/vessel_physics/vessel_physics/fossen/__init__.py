"""
The Fossen matrix model of small craft (Fossen 2021).

The form of PythonVehicleSimulator's Otter, Gazebo/VRX's USV plugins and twin-screw
model boats.

Read in this order: ``params`` (rigid body, added mass, damping, thrusters and rudders by
position and direction, wind areas), ``forces`` (each term of the equation of motion),
``family`` (the registry, M = M_RB + M_A and a vessel file's vectors).
"""

from vessel_physics.fossen.family import FAMILY, MODEL_TERMS

__all__ = ['FAMILY', 'MODEL_TERMS']
