"""The scale benchmark's reading of a training log (offline/benchmarks/scale)."""

import json

from offline.benchmarks.scale import trained_epochs


def test_the_reference_line_of_a_training_log_is_no_trained_epoch():
    """The log opens with the physics alone's score, untimed (make bench stopped on it)."""
    log = '\n'.join(json.dumps(r) for r in (
        {'epoch': -1, 'phase_kind': 'reference', 'val_score': 7.5},
        {'epoch': 0, 'phase_kind': 'teacher', 'val_score': 6.6, 'seconds': 1.25},
        {'epoch': 1, 'phase_kind': 'multistep', 'val_score': 5.4, 'seconds': 2.5})) + '\n'
    epochs = trained_epochs(log)
    assert [r['epoch'] for r in epochs] == [0, 1]
    assert sum(r['seconds'] for r in epochs) == 3.75
