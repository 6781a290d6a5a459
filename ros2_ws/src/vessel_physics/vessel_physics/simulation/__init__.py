"""The simulator of any family's vessel: configuration, environment, operator, sensors."""
