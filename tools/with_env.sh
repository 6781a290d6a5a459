#!/usr/bin/env bash
# Run a command in the project's environment: the venv, the built workspace, and DDS
# confined to this machine (a project default; a user's own ROS_DOMAIN_ID is kept).
set -eo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck disable=SC1091
source "$ROOT/.venv/bin/activate"
# shellcheck disable=SC1091
source "$ROOT/ros2_ws/install/setup.bash"
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
export ROS_LOG_DIR="${ROS_LOG_DIR:-$ROOT/ros2_ws/log/ros}"
cd "$ROOT"
exec "$@"
