#!/usr/bin/env bash
# Configures and builds the main tree (build/): core, Python module, engine, add-on zip.
set -euo pipefail
cd "$(dirname "$0")/.."
WERROR=OFF
if [ "${CI:-}" = "true" ] || [ "${SCHNEE_WERROR:-}" = "ON" ]; then WERROR=ON; fi
cmake -S . -B build -G Ninja -DSCHNEE_WERROR=$WERROR >/dev/null
cmake --build build -j "$(nproc)"
