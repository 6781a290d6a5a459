"""
What can exist on a vessel: the candidates its description admits, and why others are out.

A candidate the vessel cannot have is not tried, because a sparse regression offered it
would use it to soak up whatever else is missing (a wind term in a towing tank). The
rules read the vessel description (``vessel_description.Vessel``), never a vessel name:

- no ``wind`` in ``environment``: no candidate of the category ``wind`` and none that
  requires a wind signal (``Candidate.requires``);
- ``waters: basin``: no ocean current (candidates of kind ``current``);
- no roll states (p, phi): no candidate acting on K only and none requiring p or phi;
- a family that cannot feel wind or a current (``Family.environment``): none of those.
"""

from __future__ import annotations

from dataclasses import dataclass

from vessel_description import Vessel
from vessel_description.vocabulary import ENVIRONMENT, ROLL_STATES
from vessel_diagnosis.library import Candidate, Library

WIND_SIGNALS = frozenset(column for column, _, _ in ENVIRONMENT['wind'])
ROLL_DOFS = 'K'


@dataclass(frozen=True)
class Exclusion:
    """Candidates of one category that the vessel description rules out, and why."""

    category: str
    candidates: tuple[str, ...]
    reasons: tuple[str, ...]

    def line(self) -> str:
        """Return the one-line account of the report, e.g. ``wind: ... (why)``."""
        return (f'{self.category}: {", ".join(self.candidates)} not tried: '
                f'{"; ".join(self.reasons)}')

    def to_dict(self) -> dict:
        """Return the findings.json record."""
        return {'category': self.category, 'candidates': list(self.candidates),
                'reasons': list(self.reasons)}


def _reason(cand: Candidate, vessel: Vessel, family) -> str | None:
    """Return why ``vessel`` cannot have ``cand``, or None when it can."""
    needs = set(cand.requires)
    for effect in ('wind', 'current'):
        if cand.category == effect and family is not None and \
                effect not in family.environment:
            return f'the {family.title} feels no {effect}'

    if 'wind' not in vessel.environment and (cand.category == 'wind' or needs & WIND_SIGNALS):
        return (f'the vessel file declares no wind sensor or wind (environment: '
                f'{list(vessel.environment)})')
    if vessel.waters == 'basin' and cand.kind == 'current':
        return 'the vessel file says the recordings come from a basin (waters: basin)'
    if not vessel.has_roll and (set(cand.dofs) == set(ROLL_DOFS) or needs & set(ROLL_STATES)):
        return f'the vessel has no roll states (states: {list(vessel.states)})'
    return None


def admissible(library: Library, vessel: Vessel, family=None
               ) -> tuple[Library, list[Exclusion]]:
    """Return the library reduced to what ``vessel`` can have, and one exclusion a category."""
    kept, out = [], {}
    for cand in library.candidates:
        why = _reason(cand, vessel, family)
        if why is None:
            kept.append(cand)
            continue
        names, reasons = out.setdefault(cand.category, ([], []))
        names.append(cand.name)
        if why not in reasons:
            reasons.append(why)
    exclusions = [Exclusion(category, tuple(names), tuple(reasons))
                  for category, (names, reasons) in out.items()]
    return Library(kept, library.family), exclusions
