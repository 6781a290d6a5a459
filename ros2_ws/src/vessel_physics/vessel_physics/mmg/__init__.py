"""
The MMG standard model of single-screw, single-rudder ships (Yasukawa & Yoshimura 2015).

Read in this order: ``params`` (particulars and the published non-dimensional
coefficients, and Froude scaling), ``forces`` (hull, propeller, rudder, inertial and
constant forces), ``family`` (the registry, the mass matrix, a vessel file's vectors),
``zigzag`` (the IMO zig-zag manoeuvre) and ``scale`` (the ``scale_physics`` program).
"""

from vessel_physics.mmg.family import FAMILY, FULL_TERMS

__all__ = ['FAMILY', 'FULL_TERMS']
