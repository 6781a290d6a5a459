"""
ROS-free diagnosis of simulation-to-reality mismatch of the vessel physics.

Locate where a nominal physics departs from recordings, name the missing physics with a
library of candidate terms, write the augmented physics and show the gain on held-out
recordings (docs/diagnosis.md).
"""
