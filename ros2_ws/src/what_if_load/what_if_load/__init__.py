"""
The service soak's what-if clients in C over rcl (``python -m what_if_load --help``).

A Python client converts every answer it receives to Python objects under its own
interpreter lock, 64 Forecast messages of a 1.65 MB answer at a time, and a "busy"
answer that arrives meanwhile waits: the soak would count the client's wait against the
node. These clients run in C, the lock released, so the soak measures the node.
"""
