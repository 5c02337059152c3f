#!/usr/bin/env bash
# Set up the workspace (idempotent) and run the whole test suite.
#   bash scripts/test.sh                 # everything
#   bash scripts/test.sh tests/control   # any pytest arguments
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$ROOT/scripts/setup.sh"
# shellcheck source=/dev/null
. "$ROOT/scripts/env.sh"
cd "$ROOT"
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST  # tests never leave loopback, whatever the caller's shell says
exec python -m pytest -p no:cacheprovider "${@:-tests}"
