#!/usr/bin/env bash
# Candidate data for the next default model (issue #11 follow-up, MODEL_CARD.md "next steps"):
# the same photo scenes with the dslr-840-mild profile, and a held-out set of 40 sequences.
# Every step resumes. Writes runs/data/ (ignored by git).
set -euo pipefail
DP=${DP:-.venv/bin/dualpixel}
SYN="--cameras dslr-840-mild --psf-bank pixel4 --noise-model poisson-gaussian"
SYN="$SYN --noise-sigmas 0.006,0.009,0.013,0.018,0.025 --bit-depth 8"
$DP -q scenes --output runs/data/photo-train --sequences 200 --frames 4 --size 840x560 --layout photo --seed 0
$DP -q synth --input runs/data/photo-train --output runs/data/photo-mild-synth-train --split train $SYN --seed 0 --workers 2
$DP -q scenes --output runs/data/photo-test40 --sequences 40 --frames 4 --size 840x560 --layout photo --seed 1000
$DP -q synth --input runs/data/photo-test40 --output runs/data/photo-mild-synth-test40 --split test $SYN --seed 1000 --workers 2
