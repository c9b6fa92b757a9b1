#!/usr/bin/env bash
# Data for the fine-tuned default model (issue #11, MODEL_CARD.md "Fine-tuning on more scenes"):
# 800 new photo scenes of one frame each (scene diversity, not frames of the same scene), each
# synthesised with both defocus profiles (dslr-840 and dslr-840-mild), and a held-out set of 40
# further scenes made the same way. Every step resumes. Writes runs/data/ (ignored by git).
# WORKERS (default 2) sets the parallel processes; the data do not depend on it. Rendering stays
# on the CPU (--device cpu) also where a GPU is present, so every machine makes the same data.
set -euo pipefail
DP=${DP:-.venv/bin/dualpixel}
W=${WORKERS:-2}
SYN="--cameras dslr-840,dslr-840-mild --psf-bank pixel4 --noise-model poisson-gaussian"
SYN="$SYN --noise-sigmas 0.006,0.009,0.013,0.018,0.025 --bit-depth 8 --device cpu"
$DP -q scenes --output runs/data/mix-scenes-test --sequences 40 --frames 1 --size 840x560 --layout photo --seed 21000 --workers "$W" &
$DP -q scenes --output runs/data/mix-scenes-train --sequences 800 --frames 1 --size 840x560 --layout photo --seed 20000 --workers "$W"
wait
$DP -q synth --input runs/data/mix-scenes-test --output runs/data/mix-synth-test --split test $SYN --seed 21000 --workers "$W"
$DP -q synth --input runs/data/mix-scenes-train --output runs/data/mix-synth-train --split train $SYN --seed 20000 --workers "$W"
