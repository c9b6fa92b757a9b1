#!/usr/bin/env bash
# Stage 10 of the default model: both stages trained together (configs/rdpd-light-joint-cpu.yaml); resumable.
exec "$(dirname "$0")/train_resumable.sh" configs/rdpd-light-joint-cpu.yaml runs/train/rdpd-joint2
