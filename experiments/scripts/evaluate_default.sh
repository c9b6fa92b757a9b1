#!/usr/bin/env bash
# The numbers of the model card: a checkpoint (default: the shipped rdpd-light) on the held-out
# synthetic test set (scripts/make_mix_data.sh) and on the real Canon DP scenes (../shared), with
# the published DPDNet beside it. Further arguments go to both evaluations (e.g. --multiscale).
# Usage: scripts/evaluate_default.sh [CHECKPOINT [OUTPUT [EVAL OPTIONS...]]]
set -euo pipefail
DP=${DP:-.venv/bin/dualpixel}
CKPT=${1:-rdpd-light}
OUT=${2:-runs/eval}
$DP eval --dataset runs/data/mix-synth-test --split test --checkpoint "$CKPT" --no-niqe \
    --output "$OUT/mix-test" "${@:3}"
$DP eval --dataset ../shared/data/canon-dp-real --checkpoint "$CKPT" --output "$OUT/canon" "${@:3}"
