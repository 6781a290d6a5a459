#!/usr/bin/env bash
# The main job (`make demo`): run through tools/with_env.sh. Extra arguments go to
# offline/demo.py (see `python offline/demo.py --help`).
set -euo pipefail
export ROS_DOMAIN_ID="${DEMO_ROS_DOMAIN_ID:-$((150 + $$ % 50))}"
exec python offline/demo.py "$@"
