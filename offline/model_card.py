#!/usr/bin/env python3
"""
Write a model card for a hybrid checkpoint: what it is, what it learned from, how good.

    python offline/model_card.py CHECKPOINT --dataset DIR --out DIR

The ``model_card`` program of hybrid_models: evaluates the checkpoint with the compiled
forecast engine on the test split of a dataset and writes MODEL_CARD.md and
model_card.json (``--help`` for the options); ``ros2 run hybrid_models model_card`` is
the same program installed.
"""

import sys

from hybrid_models.cli.model_card import main

if __name__ == '__main__':
    sys.exit(main())
