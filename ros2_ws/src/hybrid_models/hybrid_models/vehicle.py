"""
What the learning layer knows about a vehicle: its vessel description.

Models and training see only state and control vectors plus this description (names,
units, sample rate, window and horizon), so another vessel -- or another kind of
vehicle -- is a new vessel file, not new learning code. ``VehicleSpec`` is the learning
layer's name for ``vessel_description.Vessel``; there is one class.
"""

from __future__ import annotations

from vessel_description import Vessel, VesselError, load_vessel

VehicleSpec = Vessel

__all__ = ['VehicleSpec', 'VesselError', 'load_vessel']
