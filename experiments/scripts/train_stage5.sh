#!/usr/bin/env bash
# Candidate stage 5 of the default model (configs/rdpd-light-stage5-cpu.yaml); resumable.
exec "$(dirname "$0")/train_resumable.sh" configs/rdpd-light-stage5-cpu.yaml runs/train/rdpd-stage5-revived
