#!/usr/bin/env bash
# The default model's first stage, rdpd-light-photo (issue #11, MODEL_CARD.md); resumable. Run in
# the background: nohup scripts/train_default.sh > runs/train.log &
exec "$(dirname "$0")/train_resumable.sh" configs/rdpd-light-photo-cpu.yaml runs/train/rdpd-photo
