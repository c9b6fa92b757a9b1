#!/usr/bin/env bash
# Candidate stage 4 of the default model (configs/rdpd-light-stage4-cpu.yaml); resumable.
exec "$(dirname "$0")/train_resumable.sh" configs/rdpd-light-stage4-cpu.yaml runs/train/rdpd-stage4-p256
