#!/usr/bin/env bash
# The main job on a fresh machine: set up, then run the paper scenario on the MuJoCo plant
# (300 s, PI baseline beside it), writing video, figures, MCAP log, summary and report to
# renders/paper/. Extra arguments go to `usv-mj run` (try --help).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec "${PYTHON:-python3}" -m usv_mj.cli run --overwrite "$@"   # a second main job replaces the first
