"""
What the learning layer knows about a vehicle: vector names, units and sample rate.

Models and training see only state and control vectors plus this description, so a
quadcopter can be added as another ``VehicleSpec`` without touching the learning code.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass


@dataclass(frozen=True)
class VehicleSpec:
    """Names and units of a vehicle's model vectors and its sampling rate."""

    name: str
    state_names: tuple[str, ...]
    state_units: tuple[str, ...]
    control_names: tuple[str, ...]
    control_units: tuple[str, ...]
    rate_hz: float

    @property
    def n_state(self) -> int:
        """Return the number of state variables."""
        return len(self.state_names)

    @property
    def n_control(self) -> int:
        """Return the number of control/input variables."""
        return len(self.control_names)

    @property
    def dt(self) -> float:
        """Sample period (s)."""
        return 1.0 / self.rate_hz

    def state_index(self, name: str) -> int:
        """Column of a state variable."""
        return self.state_names.index(name)

    def control_index(self, name: str) -> int:
        """Column of a control variable."""
        return self.control_names.index(name)

    def to_dict(self) -> dict:
        """JSON-ready description."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, d: dict) -> VehicleSpec:
        """Inverse of ``to_dict``."""
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in d.items()})


# docs/conventions.md: z = [u, v, p, r, phi] (FRD), c = [n, delta_port, delta_stbd,
# wind_speed, wind_dir_cos, wind_dir_sin], 1 Hz.
SHIP = VehicleSpec(
    name='ship',
    state_names=('u', 'v', 'p', 'r', 'phi'),
    state_units=('m/s', 'm/s', 'rad/s', 'rad/s', 'rad'),
    control_names=('n', 'delta_port', 'delta_stbd', 'wind_speed', 'wind_dir_cos',
                   'wind_dir_sin'),
    control_units=('rad/s', 'rad', 'rad', 'm/s', '1', '1'),
    rate_hz=1.0,
)
