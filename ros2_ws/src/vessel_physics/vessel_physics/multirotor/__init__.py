"""
The multirotor family: rotorcraft in six degrees of freedom (rotorpy's model).

Read in this order: ``params`` (rigid body, rotors by position and spin, rotor
aerodynamics), ``forces`` (each term of the equation of motion), ``family`` (the
registry, M = diag(m, m, m, I), the attitude kinematics and a vessel file's vectors).
"""

from vessel_physics.multirotor.family import FAMILY, MINQ_TERMS, MODEL_TERMS

__all__ = ['FAMILY', 'MINQ_TERMS', 'MODEL_TERMS']
