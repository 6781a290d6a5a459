"""`ros2 run hybrid_predictor predictor`: malloc arenas limited first, then the node."""

import sys

from vessel_ros_bridge.allocator import start_node


def main(args=None) -> int:
    """Run ``hybrid_predictor.node.main`` once the process's arenas are limited."""
    return start_node('hybrid_predictor.node', args)


if __name__ == '__main__':
    sys.exit(main())
