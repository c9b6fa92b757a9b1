#!/usr/bin/env bash
# Candidate stage 9 of the default model: its refiner trained on (configs/rdpd-light-refiner-cpu.yaml); resumable.
exec "$(dirname "$0")/train_resumable.sh" configs/rdpd-light-refiner-cpu.yaml runs/train/rdpd-refiner
