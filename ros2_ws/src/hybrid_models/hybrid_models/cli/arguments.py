"""Argument types the programs share (torch-free, so serving-side programs stay so)."""

import argparse
import math


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
