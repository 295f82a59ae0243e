#!/usr/bin/env bash
# The main job on the bundled default scene. Installs missing dependencies, builds, then runs.
set -euo pipefail
cd "$(dirname "$0")"
scripts/deps.sh
scripts/build.sh
exec /usr/bin/python3 scripts/main_job.py "$@"
