"""Vessel descriptions: the one source of every state and control vector layout."""

from .vessel import Actuator, Vessel, VesselError, load_vessel, parse_vessel, shipped_vessels

__all__ = ['Actuator', 'Vessel', 'VesselError', 'load_vessel', 'parse_vessel',
           'shipped_vessels']
