#!/usr/bin/env bash
# Stage 12 of the default model (shipped): stage 11's recipe again, over 14 epochs (configs/rdpd-light-stage12-cpu.yaml); resumable.
exec "$(dirname "$0")/train_resumable.sh" configs/rdpd-light-stage12-cpu.yaml runs/train/rdpd-stage12
