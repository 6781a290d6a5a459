"""
Which vessel description the predictor serves with (no ROS).

The model fixes the vessel's contract (name, states, controls, rate); the vessel file
says what a deployment needs besides: the topics and message types, the plausible
ranges of states, actuators and wind. Those are facts about the vessel, revised without
retraining, so the predictor takes them from a vessel file when there is one:

1. the ``vessel`` parameter (a file, or the name of a shipped one), whose contract must
   be the model's (refused in one line otherwise);
2. else the vessel file shipped under the model's vessel name, if its contract is the
   model's;
3. else the description the checkpoint carries.
"""

from __future__ import annotations

from vessel_description import Vessel, load_vessel, shipped_vessels


def served_vessel(parameter: str, model_vessel: Vessel, model: str) -> tuple[Vessel, str]:
    """Return (the vessel description to serve with, where it came from, for the log)."""
    if parameter:
        vessel = load_vessel(parameter)
        vessel.check_compatible(model_vessel, f'model {model}')
        return vessel, f'vessel file {vessel.source}'
    if model_vessel.name in shipped_vessels():
        shipped = load_vessel(model_vessel.name)
        if shipped.contract() == model_vessel.contract():
            return shipped, f"shipped vessel file {shipped.source} (the model's vessel)"
    return model_vessel, f'the description in model {model}'
