"""
The recording formats, one reader each (the interface: ``vessel_datasets.sources``).

``bags``: rosbag2 (MCAP, sqlite3); ``tables``: text tables by a column map;
``dataflash``: ArduPilot ``.bin`` logs; ``ulog``: PX4 ``.ulg`` logs. A new format is
one more file here with a ``find`` and a ``read``.
"""
