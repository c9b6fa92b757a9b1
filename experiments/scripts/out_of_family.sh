#!/usr/bin/env bash
# Cameras outside the family (issue #54; docs/log/2026-11-28-twelfth-session.md): twelve new
# scenes synthesised six ways no shipped model was trained on, each model scored as it ships.
# Resumable (every step skips what it finished). About 30 minutes on 2 cores.
#   bash experiments/scripts/out_of_family.sh [OUT]   # default runs/out-of-family
# A model shipped later, its rows added to the model card's table (about 12 minutes):
#   MODELS=rdpd-light.v16 bash experiments/scripts/out_of_family.sh  # then, for its rows:
#   python experiments/scripts/out_of_family.py --models rdpd-light.v16 \
#       --csv docs/results/outside-family.csv --append
set -euo pipefail
cd "$(dirname "$0")/../.."
DP=".venv/bin/dualpixel -q"
OUT=${1:-runs/out-of-family}
SCENES=${SCENES:-12}
MODELS=${MODELS:-"rdpd-light.v15 rdpd-light.v12 rdpd-wide.v2"}
FAMILY_NOISE="--noise-model poisson-gaussian --noise-sigmas 0.006,0.009,0.013,0.018,0.025 --bit-depth 8"
declare -A SETS=(
  [paper]="--settings paper"
  [disk]="--psf-model disk --lens-sets dslr-840 --light linear $FAMILY_NOISE"
  [gaussian]="--psf-model gaussian --lens-sets dslr-840-mild --light linear $FAMILY_NOISE"
  [punnappurath]="--psf-model punnappurath --lens-sets dslr-840 --light linear $FAMILY_NOISE"
  [phone-noisy]="--camera pixel4 --psf-shapes bank --psf-bank pixel4 --lens-sets phone-2016-crop --grey --noise-model poisson-gaussian --noise-sigmas 0.05,0.06,0.07 --bit-depth 8"
  [large-blur]="--psf-bank broad --lens-sets dslr-1680-crop --light linear $FAMILY_NOISE"
)
mkdir -p "$OUT"
[ -f "$OUT/scenes/.done" ] || { rm -rf "$OUT/scenes"
  $DP scenes -o "$OUT/scenes" --layout photo --size 840x560 --sequences "$SCENES" --frames 1 \
    --seed 51000 && touch "$OUT/scenes/.done"; }
for set in paper disk gaussian punnappurath phone-noisy large-blur; do
  # shellcheck disable=SC2086  # the options are words
  $DP synth --input "$OUT/scenes" -o "$OUT/data/$set" --split test --seed 51000 ${SETS[$set]}
  for model in $MODELS; do
    [ -f "$OUT/eval/$set/$model/summary.json" ] || $DP eval --dataset "$OUT/data/$set" \
      --split test --checkpoint "$model" --no-niqe --figures 0 -o "$OUT/eval/$set/$model" \
      > /dev/null
  done
  echo "$set done $(date +%T)"
done
case "$MODELS" in  # the comparison table reads the three models of the first run
  *rdpd-light.v12*) .venv/bin/python experiments/scripts/out_of_family.py "$OUT" ;;
esac
