"""The one exception type for bad configuration and parameter files."""

from __future__ import annotations

from collections.abc import Iterable
import difflib


class ConfigError(ValueError):
    """A configuration value is invalid; the message is one line naming key and allowed range."""


def did_you_mean(key: str, candidates: Iterable[str]) -> str:
    """Return ``" (did you mean 'x'?)"`` for the closest candidate, or ``''``."""
    close = difflib.get_close_matches(key, sorted(candidates), n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ''
