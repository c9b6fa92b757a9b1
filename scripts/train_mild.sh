#!/usr/bin/env bash
# Candidate next default model on the dslr-840-mild data; resumes runs/train/rdpd-mild if present.
set -euo pipefail
OUT=runs/train/rdpd-mild
RESUME=""; [ -f $OUT/last_state.pt ] && RESUME="--resume"
exec ${DP:-.venv/bin/dualpixel} train --config configs/rdpd-light-mild-cpu.yaml --output $OUT $RESUME --no-progress
