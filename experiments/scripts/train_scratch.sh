#!/usr/bin/env bash
# Candidate fourth generation of the default model (configs/rdpd-light-scratch-cpu.yaml); resumable.
exec "$(dirname "$0")/train_resumable.sh" configs/rdpd-light-scratch-cpu.yaml runs/train/rdpd-scratch
