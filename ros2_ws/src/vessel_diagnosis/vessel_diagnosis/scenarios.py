"""
Concealed-effect scenarios (config/scenarios.yaml) and their simulated recordings.

Each vessel of the file (one per physics family: the patrol boat, the KVLCC2 model, the
Otter, the Crazyflie) has its scenarios. ``simulate_scenario(name, out, runs, hours,
seed, vessel=...)`` writes a dataset (the format of ``vessel_datasets.format``) from the
simulator with the scenario's effect, plus ``nominal_physics.yaml`` (and its parameter
file) beside it: the physics that lacks the effect. The manifest keeps every run's sea
state, wind, current (a multirotor's trajectory kind and settings) and, where the
scenario spreads parameters over runs, their values (the truth, for checking what was
found).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path

import numpy as np
import yaml

from vessel_datasets.format import write_dataset
from vessel_datasets.synthetic import simulated_run_table, simulation_vessel
from vessel_diagnosis.settings import config_dir
from vessel_physics.errors import ConfigError
from vessel_physics.family import Physics
from vessel_physics.physics_file import load_physics, write_parameters, write_physics
from vessel_physics.simulation.config import DEFAULT_VESSEL, SimConfig, load_simulation
from vessel_physics.simulation.simulator import Simulator


@lru_cache(maxsize=1)
def load_scenario_file() -> dict:
    """Return config/scenarios.yaml as a mapping."""
    return yaml.safe_load((config_dir() / 'scenarios.yaml').read_text())


def scenario_names(vessel: str = DEFAULT_VESSEL) -> list[str]:
    """Return the scenarios of a vessel (ConfigError, one line, for a vessel without any)."""
    vessels = load_scenario_file()['vessels']
    if vessel not in vessels:
        raise ConfigError(f'no scenarios for vessel {vessel!r}; vessels with scenarios: '
                          f'{", ".join(vessels)}')
    return list(vessels[vessel]['scenarios'])


@dataclass(frozen=True)
class Scenario:
    """A concealed effect: how to simulate it and what the diagnosis must name."""

    name: str
    vessel: str
    description: str
    simulation: SimConfig
    nominal: Physics
    expect: tuple[str, ...]
    status: str
    affected_states: tuple[str, ...]
    run_spread: Mapping[str, float] = field(default_factory=dict)

    def run_physics(self, seed: int, run: int) -> Physics:
        """
        Return the simulated physics of one run.

        With ``run_spread``, each named parameter is the scenario's value times
        (1 + spread z), z standard normal drawn from (seed, run): a vessel whose
        parameter differs from run to run, which one global coefficient cannot fit.
        """
        physics = self.simulation.physics
        if not self.run_spread:
            return physics
        rng = np.random.default_rng([seed, run])
        return physics.with_parameters(**{
            name: physics.parameter(name) * (1.0 + spread * rng.standard_normal())
            for name, spread in self.run_spread.items()})


def _merge(base: dict, over: dict) -> dict:
    out = dict(base)
    for key, value in over.items():
        out[key] = _merge(out[key], value) if isinstance(value, dict) and isinstance(
            out.get(key), dict) else value
    return out


def load_scenario(name: str, overrides: dict | None = None,
                  vessel: str = DEFAULT_VESSEL) -> Scenario:
    """Build a scenario; ``overrides`` are extra simulation keys (e.g. fewer wave components)."""
    names = scenario_names(vessel)
    if name not in names:
        raise KeyError(f'unknown scenario {name!r} of vessel {vessel!r}; known: '
                       f'{", ".join(names)}')
    data = load_scenario_file()['vessels'][vessel]
    spec = data['scenarios'][name]
    sim_dict = _merge(_merge({**data.get('simulation', {}), 'vessel': vessel},
                             spec.get('simulation', {})), overrides or {})
    cfg = load_simulation(sim_dict)
    nominal = cfg.physics
    if spec.get('truth_parameters'):
        cfg = replace(cfg, physics=cfg.physics.with_parameters(**spec['truth_parameters']))
    if spec.get('nominal_terms'):
        nominal = nominal.replace(terms=tuple(spec['nominal_terms']))
    if spec.get('nominal_factors'):
        nominal = nominal.with_parameters(**{
            name: nominal.parameter(name) * factor
            for name, factor in spec['nominal_factors'].items()})
    nominal = nominal.replace(source=f'scenario {vessel}/{name}')
    expect = tuple(spec.get('expect', ()))
    status = str(spec.get('status', 'findings' if expect else 'nothing_significant'))
    return Scenario(name, vessel, str(spec.get('description', '')), cfg, nominal, expect,
                    status, tuple(spec.get('affected_states', ())),
                    dict(spec.get('run_spread', {})))


def simulate_scenario(name: str, out: str | Path, runs: int, hours: float, seed: int,
                      overrides: dict | None = None, chunk: int = 16,
                      vessel: str = DEFAULT_VESSEL) -> Path:
    """Write the scenario's dataset and nominal physics into ``out``; return ``out``."""
    scenario = load_scenario(name, overrides, vessel)
    cfg = scenario.simulation
    out = Path(out)
    tables, sources = {}, {}
    seconds = hours * 3600.0
    description = simulation_vessel(cfg)
    chunk = 1 if scenario.run_spread else chunk       # one physics per run
    for first in range(0, runs, chunk):
        n = min(chunk, runs - first)
        physics = scenario.run_physics(seed, first)
        sim = Simulator(replace(cfg, physics=physics), n_runs=n, seed=seed, run_offset=first)
        data = sim.run(seconds)
        for j in range(n):
            run_id = f'run_{first + j:03d}'
            tables[run_id] = simulated_run_table(data, j, description)
            source = {'scenario': name, 'seed': seed, 'run_index': first + j,
                      'wind_mean_speed_mps': float(sim.wind.mean_speed[j]),
                      'current_speed_mps': float(sim.current.speed0[j]),
                      'current_direction_rad': float(sim.current.direction[j])}
            if scenario.run_spread:
                source['parameters'] = {p: physics.parameter(p) for p in scenario.run_spread}
            if sim.waves.active:
                source.update({'wave_hs_m': float(sim.waves.hs[j]),
                               'wave_tp_s': float(sim.waves.tp[j])})
            if sim.flies:          # a multirotor's trajectory kind and its settings
                source.update(sim.operator.trajectories.describe(j))
            sources[run_id] = source
    provenance = {'tool': 'vessel_diagnosis.scenarios', 'scenario': name, 'vessel': vessel,
                  'description': scenario.description, 'expect': list(scenario.expect),
                  'config': cfg.to_dict(), 'seed': seed, 'runs': runs, 'hours': hours}
    write_dataset(out, tables, vessel=description, provenance=provenance, seed=seed,
                  run_sources=sources)
    nominal = scenario.nominal
    parameters = nominal.parameters_file
    if parameters is None or load_physics(parameters).params != nominal.params:
        parameters = 'nominal_parameters.yaml'
        write_parameters(nominal, out / parameters,
                         f'Nominal parameters of scenario {vessel}/{name!r}.')
    write_physics(nominal, out / 'nominal_physics.yaml', parameters,
                  f'Nominal physics of scenario {vessel}/{name!r}: what the diagnosis is told.')
    return out
