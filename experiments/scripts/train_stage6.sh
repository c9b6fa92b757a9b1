#!/usr/bin/env bash
# Candidate stage 6 of the default model (configs/rdpd-light-stage6-cpu.yaml); resumable.
exec "$(dirname "$0")/train_resumable.sh" configs/rdpd-light-stage6-cpu.yaml runs/train/rdpd-stage6-coarse-lr
