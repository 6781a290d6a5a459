"""
The predictor's parts in C over rcl, where the interpreter lock would hold them up.

- ``door``: the predictor's ``~/predict`` service on a thread of its own, admitting at
  most ``service_capacity`` requests for the node's Python and answering the rest
  "busy" at once, with the time to come back, without the interpreter; it reads a
  request's plans into read-only records and writes an answer's Forecasts from arrays,
  where rosidl's Python messages cost a thousand-plan request a third of its time.
- ``load`` (``python -m what_if_c.load --help``): the service soak's clients, which
  convert nothing to Python, so the soak measures the node and not a client's own
  interpreter (a Python client converts each 1.65 MB answer under its lock, and a
  busy answer arriving meanwhile waits).
- ``outlet``: the node's forecasts published with the lock released while rcl hands
  them to the subscribers (rclpy holds it throughout).
- ``inlet``: the node's inputs and plans, every topic's messages taken together in the
  order DDS received them, waiting with the lock released (rclpy's executors cost a
  100 Hz state's Python turn, or read one topic's queue ahead of another's).

All are Python extensions rather than programs: the ROS wheels' librcl needs
libraries that need the interpreter's symbols.
"""
