"""Build a ControlPlan message from a matrix in a vessel's own controls (for clients)."""

from __future__ import annotations

import numpy as np

from hybrid_predictor_interfaces.msg import ControlPlan


def control_plan(vessel, values, names=None, plan_id: str = '', stamp=None,
                 step_period: float = 0.0) -> ControlPlan:
    """
    Return a ControlPlan of ``values`` (rows, len(names)) for ``vessel``.

    ``names`` default to the vessel's actuators (the environment then holds its latest
    measurement); units are the vessel file's; ``stamp`` is a builtin_interfaces/Time
    (the plan's start), left zero when None; each row holds ``step_period`` s (0: one
    forecast step).
    """
    names = list(vessel.actuator_names if names is None else names)
    units = [vessel.control_units[vessel.control_index(name)] for name in names]
    msg = ControlPlan(plan_id=plan_id, control_names=names, control_units=units,
                      values=np.asarray(values, dtype=float).ravel().tolist(),
                      step_period=float(step_period))
    if stamp is not None:
        msg.header.stamp = stamp
    return msg
