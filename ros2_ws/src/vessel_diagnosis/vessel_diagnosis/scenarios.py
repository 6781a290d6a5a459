"""
Concealed-effect scenarios (config/scenarios.yaml) and their simulated recordings.

``simulate_scenario(name, out, runs, hours, seed)`` writes a dataset (the format of
``vessel_datasets.format``) from the simulator with the scenario's effect, plus
``nominal_physics.yaml`` beside it: the physics that lacks the effect. The manifest keeps
every run's sea state, wind and current (the truth, for checking what was found).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

import yaml

from vessel_datasets.format import write_dataset
from vessel_datasets.synthetic import simulated_run_table, simulator_vessel
from vessel_diagnosis.settings import config_dir
from vessel_physics.augmented import Physics, write_physics
from vessel_physics.config import SimConfig, load_config
from vessel_physics.params import load_named_vessel
from vessel_physics.simulator import Simulator
from vessel_physics.terms import SIMULATOR_TERMS

NOMINAL_VESSEL = 'patrol_vessel.yaml'


@lru_cache(maxsize=1)
def load_scenario_file() -> dict:
    """Return config/scenarios.yaml as a mapping."""
    return yaml.safe_load((config_dir() / 'scenarios.yaml').read_text())


@dataclass(frozen=True)
class Scenario:
    """A concealed effect: how to simulate it and what the diagnosis must name."""

    name: str
    description: str
    simulation: SimConfig
    nominal: Physics
    expect: tuple[str, ...]
    status: str
    affected_states: tuple[str, ...]


def _merge(base: dict, over: dict) -> dict:
    out = dict(base)
    for key, value in over.items():
        out[key] = _merge(out[key], value) if isinstance(value, dict) and isinstance(
            out.get(key), dict) else value
    return out


def load_scenario(name: str, overrides: dict | None = None) -> Scenario:
    """Build a scenario; ``overrides`` are extra simulation keys (e.g. fewer wave components)."""
    data = load_scenario_file()
    if name not in data['scenarios']:
        raise KeyError(f'unknown scenario {name!r}; known: {", ".join(data["scenarios"])}')
    spec = data['scenarios'][name]
    sim_dict = _merge(_merge(data.get('base', {}), spec.get('simulation', {})),
                      overrides or {})
    cfg = load_config(sim_dict)
    if spec.get('truth_vessel'):
        cfg = replace(cfg, vessel=cfg.vessel.replace(**spec['truth_vessel']))
    terms = tuple(spec.get('nominal_terms', SIMULATOR_TERMS))
    nominal = Physics(load_named_vessel(NOMINAL_VESSEL), terms, vessel_file=NOMINAL_VESSEL,
                      source=f'scenario {name}')
    expect = tuple(spec.get('expect', ()))
    status = str(spec.get('status', 'findings' if expect else 'nothing_significant'))
    return Scenario(name, str(spec.get('description', '')), cfg, nominal, expect, status,
                    tuple(spec.get('affected_states', ())))


def simulate_scenario(name: str, out: str | Path, runs: int, hours: float, seed: int,
                      overrides: dict | None = None, chunk: int = 16) -> Path:
    """Write the scenario's dataset and nominal physics into ``out``; return ``out``."""
    scenario = load_scenario(name, overrides)
    cfg = scenario.simulation
    out = Path(out)
    tables, sources = {}, {}
    seconds = hours * 3600.0
    vessel = simulator_vessel(cfg.output_rate_hz)
    for first in range(0, runs, chunk):
        n = min(chunk, runs - first)
        sim = Simulator(cfg, n_runs=n, seed=seed, run_offset=first)
        data = sim.run(seconds)
        for j in range(n):
            run_id = f'run_{first + j:03d}'
            tables[run_id] = simulated_run_table(data, j, vessel)
            sources[run_id] = {
                'scenario': name, 'seed': seed, 'run_index': first + j,
                'wave_hs_m': float(sim.waves.hs[j]), 'wave_tp_s': float(sim.waves.tp[j]),
                'wind_mean_speed_mps': float(sim.wind.mean_speed[j]),
                'current_speed_mps': float(sim.current.speed0[j]),
                'current_direction_rad': float(sim.current.direction[j]),
            }
    provenance = {'tool': 'vessel_diagnosis.scenarios', 'scenario': name,
                  'description': scenario.description, 'expect': list(scenario.expect),
                  'config': cfg.to_dict(), 'seed': seed, 'runs': runs, 'hours': hours}
    write_dataset(out, tables, vessel=vessel, provenance=provenance, seed=seed,
                  run_sources=sources)
    write_physics(scenario.nominal, out / 'nominal_physics.yaml', NOMINAL_VESSEL,
                  f'Nominal physics of scenario {name!r}: what the diagnosis is told.')
    return out
