#!/usr/bin/env bash
# The default model's fine-tuning stage (configs/rdpd-light-finetune-cpu.yaml); resumes
# runs/train/rdpd-finetune if present.
set -euo pipefail
OUT=runs/train/rdpd-finetune
RESUME=""; [ -f $OUT/last_state.pt ] && RESUME="--resume"
exec ${DP:-.venv/bin/dualpixel} train --config configs/rdpd-light-finetune-cpu.yaml --output $OUT $RESUME --no-progress
