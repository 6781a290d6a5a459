"""
ROS-free models and training for multistep vehicle-state prediction.

Regression components, QLag, the LSTM baseline, the constrained hybrid residual model,
two-phase training, metrics and checkpoints.
"""
