#!/usr/bin/env bash
# Candidate stage 3 of the default model (configs/rdpd-light-stage3-cpu.yaml); resumable.
exec "$(dirname "$0")/train_resumable.sh" configs/rdpd-light-stage3-cpu.yaml runs/train/rdpd-stage3-log
