"""`ros2 run ship_sim_node simulator`: the simulator node, its malloc arenas limited first."""

import sys

from vessel_ros_bridge.allocator import start_node


def main(args=None) -> int:
    """Start the simulator (``ship_sim_node.node.main``) in a process of two arenas."""
    return start_node('ship_sim_node.node', args)


if __name__ == '__main__':
    sys.exit(main())
