#!/usr/bin/env bash
# Usage: scripts/train_resumable.sh CONFIG OUTPUT [TRAIN OPTIONS...]
# One `dualpixel train` run that resumes OUTPUT when it holds a finished epoch (last_state.pt) and
# starts it otherwise; the per-model scripts (train_default.sh, ...) call this.
set -euo pipefail
CONFIG=$1; OUT=$2
RESUME=""; [ -f "$OUT/last_state.pt" ] && RESUME="--resume"
exec ${DP:-.venv/bin/dualpixel} train --config "$CONFIG" --output "$OUT" $RESUME --no-progress "${@:3}"
