"""Argument types the programs share (torch-free, so serving-side programs stay so)."""

import argparse
from functools import partial
import math
import sys

from tqdm import tqdm


def threshold(text: str) -> float | None:
    """Parse 'none' or a number >= 0."""
    if text.lower() == 'none':
        return None
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected a number >= 0 or 'none', got {text!r}") from None
    if not value >= 0 or math.isinf(value):
        raise argparse.ArgumentTypeError(f'the threshold must be finite and >= 0, got {text}')
    return value


def progress(description: str):
    """Return a wrapper showing a progress bar on stderr while an iterable is consumed."""
    return partial(tqdm, desc=description, file=sys.stderr)
