#!/usr/bin/env bash
# The shipped rdpd-light training run (issue #11, MODEL_CARD.md): resumes the run folder when it
# holds a finished epoch. Run in the background: nohup scripts/train_default.sh > runs/train.log &
set -euo pipefail
OUT=runs/train/rdpd-photo
RESUME=""; [ -f $OUT/last_state.pt ] && RESUME="--resume"
exec ${DP:-.venv/bin/dualpixel} train --config configs/rdpd-light-photo-cpu.yaml --output $OUT $RESUME --no-progress
