#!/usr/bin/env bash
# Candidate default model on the dslr-840-mild data (MODEL_CARD.md, not shipped); resumable.
exec "$(dirname "$0")/train_resumable.sh" configs/rdpd-light-mild-cpu.yaml runs/train/rdpd-mild
