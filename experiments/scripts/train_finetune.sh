#!/usr/bin/env bash
# The default model's fine-tuning stage (configs/rdpd-light-finetune-cpu.yaml); resumable.
exec "$(dirname "$0")/train_resumable.sh" configs/rdpd-light-finetune-cpu.yaml runs/train/rdpd-finetune
