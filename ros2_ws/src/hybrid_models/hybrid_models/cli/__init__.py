"""Command-line programs of the models layer: ``train`` and ``evaluate`` (also offline/*.py)."""
