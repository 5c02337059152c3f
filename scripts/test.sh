#!/usr/bin/env bash
# Set up the workspace (idempotent), lint the repository and run the whole test suite.
#   bash scripts/test.sh                 # everything
#   bash scripts/test.sh tests/control   # any pytest arguments
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$ROOT/scripts/setup.sh"
# shellcheck source=/dev/null
. "$ROOT/scripts/env.sh"
cd "$ROOT"
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST  # tests never leave loopback, whatever the caller's shell says
ruff check --no-cache .  # the lint of ruff.toml: a finding fails the run before any test starts
exec python -m pytest -p no:cacheprovider "${@:-tests}"
