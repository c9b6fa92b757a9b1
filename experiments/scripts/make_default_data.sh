#!/usr/bin/env bash
# Data of the default model's first stage (rdpd-light-photo; issue #11, MODEL_CARD.md). That stage
# was trained on data made before commit 58047ce, when every sequence reused the first one's camera;
# this script now draws a camera per scene, so it makes the intended, different data. Every step
# resumes: rerun after an interruption. Writes runs/data/ (ignored by git). About 12 minutes on 2 cores.
set -euo pipefail
DP=${DP:-.venv/bin/dualpixel}
SYN="--cameras dslr-840 --psf-bank pixel4 --noise-model poisson-gaussian"
SYN="$SYN --noise-sigmas 0.006,0.009,0.013,0.018,0.025 --bit-depth 8"
$DP scenes --output runs/data/photo-test --sequences 8 --frames 4 --size 840x560 --layout photo --seed 1000
$DP synth --input runs/data/photo-test --output runs/data/photo-synth-test --split test $SYN --seed 1000 --workers 2
$DP scenes --output runs/data/photo-train --sequences 200 --frames 4 --size 840x560 --layout photo --seed 0
$DP synth --input runs/data/photo-train --output runs/data/photo-synth-train --split train $SYN --seed 0 --workers 2
