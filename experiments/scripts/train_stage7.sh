#!/usr/bin/env bash
# Candidate stage 7 of the default model (configs/rdpd-light-stage7-cpu.yaml); resumable.
exec "$(dirname "$0")/train_resumable.sh" configs/rdpd-light-stage7-cpu.yaml runs/train/rdpd-stage7-p256
