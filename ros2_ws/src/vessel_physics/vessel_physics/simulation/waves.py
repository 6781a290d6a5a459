"""
Irregular waves (JONSWAP) and their first-order forces on the hull (numpy, simulator only).

Sea state. Per run: significant wave height Hs, peak period Tp scattered around the mean
relation Tp = 4.883 + 2.68 Hs^0.54 s, and a mean direction the waves travel *to*
(NED, from north towards east). The JONSWAP spectrum (Hasselmann et al. 1973)

    S(w) = (1 - 0.287 ln g) (5/16) Hs^2 w0^4 w^-5 exp(-1.25 (w0/w)^4) g^r,
    r = exp(-(w - w0)^2 / (2 s^2 w0^2)),

with g = 3.3, s = 0.07 (w <= w0) / 0.09 and w0 = 2 pi / Tp is cut into N equal bins over
[f_lo w0, f_hi w0]; each bin gets one frequency drawn uniformly inside it (so the record
does not repeat within an hour), amplitude a_k = sqrt(2 S(w_k) dw) and a random phase.
Short-crestedness: each component travels in the mean direction plus a normal spread
(one direction per frequency, the usual single-direction-per-frequency scheme).
Deep water: k = w^2 / g.

Phase and encounter frequency. Component k's phase at the hull is
theta_k = w_k t - k_k (x cos chi_k + y sin chi_k) + eps_k with the ship's NED position
(x, y). Its rate is w_k - k_k U cos beta_k, the encounter frequency w_e (Fossen 2011),
with beta_k = chi_k - psi (0 following, pi head sea), and it stays right while speed and
heading change, which w_e t does not.

Force model (parametric; no RAO table of any vessel is used). The first-order force is
the Froude-Krylov force of the undisturbed wave pressure p = rho g a e^(-k z) cos(...)
integrated over a box hull of length Lpp, beam B and draught T centred on CO, scaled by
per-DOF gains that stand for diffraction and the hull's real shape:

- surge, sway: X, Y = -rho g a L B (1 - e^(-kT)) S_L S_B (cos beta, sin beta) sin theta,
  S_L = sinc(k L cos beta / 2), S_B = sinc(k B sin beta / 2): proportional to cos beta and
  sin beta, cancelling when the wave length fits the hull (band-limited);
- roll: effective wave slope, K = -rho g nabla GM k a sin beta S_L S_B
  ((1 - e^(-kT)) / (kT)) sin theta: the hydrostatic roll moment of the local wave slope
  averaged over the hull and draught (a surface sloping up to starboard rolls the ship to
  port). Its gain is an effective wave-slope coefficient;
- yaw: N = rho g a (1 - e^(-kT)) cos theta [sin beta B S_B (L^2/2) j1(k L cos beta / 2)
  - cos beta L S_L (B^2/2) j1(k B sin beta / 2)], j1(s) = (sin s - s cos s) / s^2 (the
  spherical Bessel function; sinc = j0), which
  goes as sin(2 beta) k^2 L B T (L^2 - B^2) / 12 for long waves and vanishes for waves much
  shorter than the hull.

Assumptions: deep water, linear (first-order) forces only, no second-order drift, no
radiation damping at wave frequencies beyond the manoeuvring model's damping, no
wave-current interaction, hull motions do not change the forces. The gains in
config/simulation.yaml are chosen so that wave-induced motions look like the data of
Baier et al.: median per-run std of p about 0.007 rad/s, r 0.002 rad/s, v 0.05 m/s, roll
angle 0.005-0.013 rad from the calmest to the roughest default seas (docs/simulator.md).
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
from scipy.special import spherical_jn

GRAVITY = 9.81  # m/s^2

SIGMA_LOW, SIGMA_HIGH = 0.07, 0.09   # JONSWAP peak widths below / above w0
TWO_PI = 2.0 * math.pi
HEADING_GRID_DEG = 1.0              # heading resolution of the tabulated directional gains
TABULATE_CHUNK = 45                 # headings per vectorized tabulation pass (memory)


def mean_peak_period(hs):
    """Return the expected JONSWAP peak period Tp (s) for significant wave height ``hs`` (m)."""
    return 4.883 + 2.68 * np.power(hs, 0.54)


def jonswap(omega, hs, tp, gamma=3.3):
    """JONSWAP wave spectrum S(omega) in m^2 s/rad for Hs (m), Tp (s) and peak factor gamma."""
    omega = np.asarray(omega, dtype=float)
    w0 = 2 * math.pi / tp
    sigma = np.where(omega <= w0, SIGMA_LOW, SIGMA_HIGH)
    peak = gamma ** np.exp(-(omega - w0) ** 2 / (2 * sigma ** 2 * w0 ** 2))
    return ((1 - 0.287 * math.log(gamma)) * (5.0 / 16.0) * hs ** 2 * w0 ** 4 * omega ** -5.0
            * np.exp(-1.25 * (w0 / omega) ** 4) * peak)


@dataclass(frozen=True)
class BoxHull:
    """The box hull the wave forces act on (``Family.wave_hull``): SI units."""

    rho: float           # water density, kg/m^3
    length: float        # m
    beam: float          # m
    draught: float       # m
    displacement: float  # m^3
    GM: float            # transverse metacentric height, m


@dataclass(frozen=True)
class WaveDraw:
    """One run's sea state and its components (SI, rad)."""

    hs: float
    tp: float
    direction: float       # mean direction the waves travel to (NED)
    omega: np.ndarray      # (N,) rad/s
    amplitude: np.ndarray  # (N,) m
    chi: np.ndarray        # (N,) travel direction of each component (NED)
    phase: np.ndarray      # (N,) rad


def draw_waves(rng: np.random.Generator, cfg) -> WaveDraw:
    """Draw one run's sea state and components from ``cfg`` (config.WavesConfig)."""
    hs = rng.uniform(*cfg.hs_m)
    tp = mean_peak_period(hs) * math.exp(cfg.tp_scatter * rng.standard_normal())
    direction = rng.uniform(0.0, 2 * math.pi)
    n = cfg.components
    w0 = 2 * math.pi / tp
    edges = np.linspace(cfg.frequency_range[0] * w0, cfg.frequency_range[1] * w0, n + 1)
    omega = rng.uniform(edges[:-1], edges[1:])
    chi = direction + math.radians(cfg.spreading_deg) * rng.standard_normal(n)
    phase = rng.uniform(0.0, 2 * math.pi, size=n)
    amplitude = np.sqrt(2.0 * jonswap(omega, hs, tp, cfg.gamma) * np.diff(edges))
    if not cfg.enabled:
        amplitude = np.zeros(n)
    return WaveDraw(hs, tp, direction, omega, amplitude, chi, phase)


class WaveField:
    """Wave elevation and first-order wave forces for a batch of runs (shape (n_runs,))."""

    def __init__(self, draws: list[WaveDraw], hull: BoxHull | None, cfg):
        self.hs = np.array([d.hs for d in draws])
        self.tp = np.array([d.tp for d in draws])
        self.direction = np.array([d.direction for d in draws])
        omega = np.stack([d.omega for d in draws])
        a = np.stack([d.amplitude for d in draws]) * cfg.force_scale
        chi = np.stack([d.chi for d in draws])
        k = omega ** 2 / GRAVITY
        self.active = bool(np.any(a > 0))
        self.omega, self.phase = omega, np.stack([d.phase for d in draws])
        self.elevation_amp = np.stack([d.amplitude for d in draws])
        self.cos_chi, self.sin_chi = np.cos(chi), np.sin(chi)
        self.kc, self.ks = k * self.cos_chi, k * self.sin_chi
        if hull is None:   # a family that feels no waves: the sea state only
            self.active = False
            return
        length, beam, draught = hull.length, hull.beam, hull.draught
        self.half_kl, self.half_kb = 0.5 * k * length, 0.5 * k * beam
        depth = 1.0 - np.exp(-k * draught)
        rho_g_a = hull.rho * GRAVITY * a
        self.surge_amp = -rho_g_a * length * beam * depth * cfg.gain_surge
        self.sway_amp = -rho_g_a * length * beam * depth * cfg.gain_sway
        self.roll_amp = (-hull.rho * GRAVITY * hull.displacement * hull.GM * a * depth
                         / draught * cfg.gain_roll)
        yaw = rho_g_a * depth * cfg.gain_yaw
        self.yaw_amp_l = yaw * beam * length ** 2 / 2.0
        self.yaw_amp_b = yaw * length * beam ** 2 / 2.0
        if self.active:
            self._tabulate()

    def shift_origin(self, x0: np.ndarray, y0: np.ndarray) -> None:
        """Move the NED origin to (x0, y0) (m) per run without moving the sea."""
        self.phase = self.phase - (self.kc * x0[:, None] + self.ks * y0[:, None])

    def phases(self, t: float, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Component phases theta (n_runs, N) in [-pi, pi] at time t (s), NED position (m)."""
        theta = self.omega * t
        theta += self.phase
        theta -= self.kc * x[:, None]
        theta -= self.ks * y[:, None]
        # sin and cos are several times slower on the large arguments an hour produces.
        theta -= TWO_PI * np.rint(theta * (1.0 / TWO_PI))
        return theta

    def elevation(self, t: float, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Return the height of the sea surface at CO (m, up positive)."""
        return np.einsum('rn,rn->r', self.elevation_amp, np.cos(self.phases(t, x, y)))

    def _directional_gains(self, psi: np.ndarray) -> np.ndarray:
        """Per-component force gains (n_runs, G, 4, N) at headings ``psi`` (n_runs, G)."""
        cos_psi, sin_psi = np.cos(psi)[:, :, None], np.sin(psi)[:, :, None]
        cos_chi, sin_chi = self.cos_chi[:, None, :], self.sin_chi[:, None, :]
        cos_b = cos_chi * cos_psi + sin_chi * sin_psi
        sin_b = sin_chi * cos_psi - cos_chi * sin_psi
        s_l, s_b = self.half_kl[:, None, :] * cos_b, self.half_kb[:, None, :] * sin_b
        # sin(s)/s and (sin s - s cos s)/s^2 are the spherical Bessel functions j0, j1.
        sinc_l, j1_l = spherical_jn(0, s_l), spherical_jn(1, s_l)
        sinc_b, j1_b = spherical_jn(0, s_b), spherical_jn(1, s_b)
        common = sinc_l * sinc_b
        lateral = sin_b * common
        return np.stack([
            self.surge_amp[:, None, :] * cos_b * common,
            self.sway_amp[:, None, :] * lateral,
            self.roll_amp[:, None, :] * lateral,
            self.yaw_amp_l[:, None, :] * sin_b * sinc_b * j1_l
            - self.yaw_amp_b[:, None, :] * cos_b * sinc_l * j1_b,
        ], axis=2)

    def _tabulate(self) -> None:
        # The gains depend on heading only through beta_k = chi_k - psi; tabulating them
        # per run over a full turn (linear interpolation in psi) replaces eight
        # transcendental functions per component and RK4 stage by a gather.
        n_grid = int(round(360.0 / HEADING_GRID_DEG))
        self._grid_step = 2 * math.pi / n_grid
        grid = np.arange(n_grid + 1) * self._grid_step
        n_runs = self.omega.shape[0]
        table = np.empty((n_runs, n_grid + 1, 4, self.omega.shape[1]))
        for g0 in range(0, n_grid + 1, TABULATE_CHUNK):
            headings = np.broadcast_to(grid[g0:g0 + TABULATE_CHUNK], (n_runs, len(
                grid[g0:g0 + TABULATE_CHUNK])))
            table[:, g0:g0 + TABULATE_CHUNK] = self._directional_gains(headings)
        self._table = table
        self._rows = np.arange(n_runs)

    def gains(self, psi: np.ndarray) -> np.ndarray:
        """Interpolate the per-DOF force gains at heading ``psi`` (rad); (n_runs, 4, N)."""
        pos = np.mod(psi, 2 * math.pi) * (1.0 / self._grid_step)
        index = np.minimum(pos.astype(np.intp), self._table.shape[1] - 2)
        frac = (pos - index)[:, None, None]
        lower = self._table[self._rows, index]
        return lower + frac * (self._table[self._rows, index + 1] - lower)

    def forces(self, t: float, x: np.ndarray, y: np.ndarray, psi: np.ndarray) -> np.ndarray:
        """First-order wave forces [X, Y, K, N] (n_runs, 4), FRD, N and N m."""
        # sin/cos of the reduced phases in single precision: numpy vectorizes them about
        # ten times faster, and 1e-7 of a random wave force is far below any model error.
        theta = self.phases(t, x, y).astype(np.float32)
        gains = self.gains(psi)
        out = np.empty((theta.shape[0], 4))
        out[:, 0:3] = np.einsum('rdn,rn->rd', gains[:, 0:3], np.sin(theta).astype(float))
        out[:, 3] = np.einsum('rn,rn->r', gains[:, 3], np.cos(theta).astype(float))
        return out
