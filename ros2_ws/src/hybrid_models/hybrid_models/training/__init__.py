"""Training: configs, the resumable fit loop with 1P/2P phases, model-family tasks."""

from hybrid_models.training.config import ConfigError, load_config, resolve
from hybrid_models.training.run import train
from hybrid_models.training.train import MODEL_FILE

__all__ = ['ConfigError', 'load_config', 'resolve', 'train', 'MODEL_FILE']
