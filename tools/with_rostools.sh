#!/usr/bin/env bash
# Run a command with the test-only ros2 CLI and launch (`tools/setup.sh rostools`)
# layered over the project's environment; run it through tools/with_env.sh:
#   tools/with_env.sh tools/with_rostools.sh ros2 topic list
set -eo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
RT="${ROSTOOLS:-$ROOT/.venv-rostools}"
if [ ! -f "$RT/.rostools-hash" ]; then
  echo "with_rostools: error: no ros2 CLI in $RT; run tools/setup.sh rostools (make test does)" >&2
  exit 1
fi
if [ -z "${AMENT_PREFIX_PATH:-}" ]; then
  echo 'with_rostools: error: run through tools/with_env.sh (the venv and workspace first)' >&2
  exit 1
fi
# shellcheck disable=SC1091
source "$RT/ros/local_setup.bash"
export PYTHONPATH="$RT/site${PYTHONPATH:+:$PYTHONPATH}"
export PATH="$RT/site/bin:$PATH"
exec "$@"
