"""
Command-line programs of the models layer (console scripts; also offline/*.py).

``train`` and ``evaluate`` one model, ``set_threshold`` and ``model_card`` for a checkpoint;
``reproduce_table2`` and ``compare_physics`` run the studies of hybrid_models.studies.
"""
