"""
A gusty, slowly veering true wind per run (the simulator's; each family's loads are terms).

Angles. The true wind blows *from* the NED direction ``from_ned`` (rad, from north towards
east); relative to the bow it comes from ``gamma = from_ned - psi``, positive towards
starboard (docs/conventions.md).

Field. Mean speed per run plus longitudinal gusts with the Harris spectrum (Fossen 2011,
8.1): S(f) = 4 kappa U^2 (L_g/U) / (2 + (L_g f / U)^2)^(5/6) in m^2/s^2 per Hz,
synthesized as a sum of sinusoids (one random frequency inside each log-spaced bin,
random phases), so speed and direction are smooth deterministic functions of time that
every RK4 stage sees consistently. The direction veers slowly as a sum of a few long-period
sinusoids.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np


def harris_spectrum(f, mean_speed, drag_coefficient, length_scale):
    """Harris gust spectrum S(f) (m^2/s^2 per Hz) for mean wind ``mean_speed`` (m/s)."""
    u = np.maximum(mean_speed, 1e-6)
    x = length_scale * f / u
    return 4.0 * drag_coefficient * u * length_scale / (2.0 + x * x) ** (5.0 / 6.0)


def _cos32(angle: np.ndarray) -> np.ndarray:
    """Cosine in single precision after reduction to [-pi, pi] (vectorized, ~1e-7)."""
    reduced = angle - (2 * math.pi) * np.rint(angle * (0.5 / math.pi))
    return np.cos(reduced.astype(np.float32)).astype(float)


@dataclass(frozen=True)
class WindDraw:
    """One run's random wind: mean, veering and gust components (SI, rad)."""

    mean_speed: float
    from_ned: float
    veer_amp: np.ndarray     # (M,) rad
    veer_omega: np.ndarray   # (M,) rad/s
    veer_phase: np.ndarray   # (M,) rad
    gust_amp: np.ndarray     # (G,) m/s
    gust_omega: np.ndarray   # (G,) rad/s
    gust_phase: np.ndarray   # (G,) rad


def draw_wind(rng: np.random.Generator, cfg) -> WindDraw:
    """Draw one run's wind from ``cfg`` (config.WindConfig) with the run's generator."""
    mean = rng.uniform(*cfg.mean_speed_mps)
    from_ned = rng.uniform(0.0, 2 * math.pi)
    m = cfg.veer_components
    periods = rng.uniform(*cfg.veer_period_s, size=m)
    veer_amp = np.full(m, math.radians(cfg.veer_std_deg) * math.sqrt(2.0 / m))
    veer_phase = rng.uniform(0.0, 2 * math.pi, size=m)
    g = cfg.gust_components
    edges = np.geomspace(*cfg.gust_frequency_hz, g + 1)
    f = rng.uniform(edges[:-1], edges[1:])
    gust_phase = rng.uniform(0.0, 2 * math.pi, size=g)
    spectrum = harris_spectrum(f, mean, cfg.gust_drag_coefficient, cfg.gust_length_scale_m)
    gust_amp = np.sqrt(2.0 * spectrum * np.diff(edges)) if cfg.gusts else np.zeros(g)
    return WindDraw(mean, from_ned, veer_amp, 2 * math.pi / periods, veer_phase, gust_amp,
                    2 * math.pi * f, gust_phase)


class WindField:
    """True wind of a batch of runs as smooth functions of time (numpy, shape (n_runs,))."""

    def __init__(self, draws: list[WindDraw]):
        self.mean_speed = np.array([d.mean_speed for d in draws])
        self.from_ned0 = np.array([d.from_ned for d in draws])
        self._veer = [np.stack([getattr(d, k) for d in draws])
                      for k in ('veer_amp', 'veer_omega', 'veer_phase')]
        self._gust = [np.stack([getattr(d, k) for d in draws])
                      for k in ('gust_amp', 'gust_omega', 'gust_phase')]
        self._cache: dict[float, tuple[np.ndarray, np.ndarray]] = {}

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Return true wind speed (m/s, >= 0) and from-direction (rad, NED) at time t (s)."""
        # RK4 asks for each time two or three times (mid-step twice, step ends shared).
        hit = self._cache.get(t)
        if hit is None:
            if len(self._cache) > 4:
                self._cache.clear()
            hit = self._cache[t] = self._evaluate(t)
        return hit

    def _evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        amp, omega, phase = self._gust
        speed = self.mean_speed + np.einsum('rg,rg->r', amp, _cos32(omega * t + phase))
        amp, omega, phase = self._veer
        from_ned = self.from_ned0 + np.einsum('rm,rm->r', amp, np.sin(omega * t + phase))
        return np.maximum(speed, 0.0), from_ned
