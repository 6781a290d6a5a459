"""
Vessel physics without ROS: families of equations of motion, and their simulator.

A family (``family.Family``) is one folder: ``patrol/`` (the 4-DOF patrol boat),
``mmg/`` (the MMG standard model of single-screw ships), ``fossen/`` (the Fossen matrix
model of small craft), ``multirotor/`` (rotorcraft in six degrees of freedom).
``physics_file.load_physics`` reads any family's file into a ``family.Physics``, which
the simulator (``simulation/``), the hybrid models and the diagnosis use. Shared maths
stays here: frames, the integrator, the Array API helpers.
"""
