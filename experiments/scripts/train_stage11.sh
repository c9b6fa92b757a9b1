#!/usr/bin/env bash
# Stage 11 of the default model (shipped): stage 10's recipe again, over 14 epochs (configs/rdpd-light-stage11-cpu.yaml); resumable.
exec "$(dirname "$0")/train_resumable.sh" configs/rdpd-light-stage11-cpu.yaml runs/train/rdpd-stage11
