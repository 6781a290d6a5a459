"""
The patrol boat: a 4-DOF coastal patrol vessel (Perez, Ross & Fossen 2006).

Read in this order: ``params`` (the coefficients, named as in the textbook), ``forces``
(rigid-body Coriolis, restoring, Blanke hull damping, twin rudder-propellers, and the
Isherwood wind loads of ``wind_loads``), ``candidates`` (effects the model lacks, for the
diagnosis), ``family`` (the registry, the mass matrix and how a vessel file's vectors
map onto the family's).
"""

from vessel_physics.patrol.family import FAMILY, MIN_TERMS, PRO_TERMS, SIMULATOR_TERMS

__all__ = ['FAMILY', 'MIN_TERMS', 'PRO_TERMS', 'SIMULATOR_TERMS']
