#!/usr/bin/env bash
# Full-width RDPD on one GPU (configs/rdpd-full-gpu.yaml, issue #11 item 4); resumable.
# Usage: scripts/train_full_gpu.sh [OUTPUT] [TRAIN OPTIONS...], e.g. --set epochs=30.
# Needs the mix data (WORKERS=14 scripts/make_mix_data.sh makes it in minutes on 16 cores).
OUT=${1:-runs/train/rdpd-full}
exec "$(dirname "$0")/train_resumable.sh" configs/rdpd-full-gpu.yaml "$OUT" "${@:2}"
