#!/usr/bin/env bash
# The numbers of the model card: the shipped rdpd-light on the held-out synthetic test set and on
# the real Canon DP scenes (../shared), with the published DPDNet beside it.
set -euo pipefail
DP=${DP:-.venv/bin/dualpixel}
CKPT=${1:-rdpd-light}
$DP eval --dataset runs/data/photo-synth-test --split test --checkpoint "$CKPT" --no-niqe \
    --output runs/eval/synth-test
$DP eval --dataset ../shared/data/canon-dp-real --checkpoint "$CKPT" --output runs/eval/canon
