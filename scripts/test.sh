#!/usr/bin/env bash
# The tests on a fresh machine: set up, then run the whole suite (slow-marked checks included).
# Extra arguments go to pytest (e.g. -k quantizer, -m "not slow").
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export MPLBACKEND=Agg
# The suite runs on every core (pytest-xdist; USV_MJ_TEST_WORKERS=0 runs it in this process, in order):
# each test writes under its own tmp_path and binds port 0, so two run side by side.
exec "${PYTHON:-python3}" -m pytest -n "${USV_MJ_TEST_WORKERS:-auto}" "$@"
