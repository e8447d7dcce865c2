#!/usr/bin/env bash
# The tests on a fresh machine: set up, then run the whole suite (slow-marked checks included).
# Extra arguments go to pytest (e.g. -k quantizer, -m "not slow").
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export MPLBACKEND=Agg
exec "${PYTHON:-python3}" -m pytest "$@"
