#!/usr/bin/env bash
# The main job: one routing episode with the offline planner and the shipped insertion policy.
# Writes runs/demo/{episode.mp4,result.json}. Extra arguments go to `dloroute route`.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec .venv/bin/dloroute route --family fixed_attribute --seed 3 --out runs/demo "$@"
