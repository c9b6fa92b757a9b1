#!/usr/bin/env bash
# Candidate stage 3 of the default model (configs/rdpd-light-stage3-cpu.yaml); resumes
# runs/train/rdpd-stage3 if present.
set -euo pipefail
OUT=runs/train/rdpd-stage3
RESUME=""; [ -f $OUT/last_state.pt ] && RESUME="--resume"
exec ${DP:-.venv/bin/dualpixel} train --config configs/rdpd-light-stage3-cpu.yaml --output $OUT $RESUME --no-progress
