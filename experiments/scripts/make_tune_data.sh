#!/usr/bin/env bash
# A second held-out set for choosing inference settings (the multiscale fusion's sigma), so the
# held-out test set of scripts/make_mix_data.sh stays untouched by any choice: 20 further photo
# scenes (seed 22000, never used in training), each with both defocus profiles, made exactly as
# the test set. Resumes. Writes runs/data/tune-synth (ignored by git).
set -euo pipefail
DP=${DP:-.venv/bin/dualpixel}
W=${WORKERS:-2}
SYN="--cameras dslr-840,dslr-840-mild --psf-bank pixel4 --noise-model poisson-gaussian"
SYN="$SYN --noise-sigmas 0.006,0.009,0.013,0.018,0.025 --bit-depth 8 --device cpu"
$DP -q scenes --output runs/data/tune-scenes --sequences 20 --frames 1 --size 840x560 --layout photo --seed 22000 --workers "$W"
$DP -q synth --input runs/data/tune-scenes --output runs/data/tune-synth --split test $SYN --seed 22000 --workers "$W"
