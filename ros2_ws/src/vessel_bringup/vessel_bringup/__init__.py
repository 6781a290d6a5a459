"""Bring the suite up: launch files, and the demo client that runs the nodes together."""
