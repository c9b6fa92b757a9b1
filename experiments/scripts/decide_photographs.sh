#!/usr/bin/env bash
# A photographic run's decision (recipes/rdpd-light-photographs.yaml, issue #77): the numbers
# its rule reads that the run's own evaluation does not make, into RUN/decision: the reference
# REF (the default the candidate would replace; tied) on the photographic held-out sets, and
# check-model of the candidate on the real pairs; then experiments/scripts/decide_photographs.py
# gives the verdict. About 20 minutes on 2 cores.
#   RUN=runs/rdpd-light-photographs TAG=rdpd-light.v17 REF=rdpd-light.v16 \
#       bash experiments/scripts/decide_photographs.sh
# (v16's own decision: RUN=runs/rdpd-light-photographs-cpu TAG=rdpd-light.v16 REF=rdpd-light.v15;
# REF=START: the shipped tag the run's first phase started from.)
set -euo pipefail
cd "$(dirname "$0")/../.."
DP=.venv/bin/dualpixel
RUN=${RUN:-runs/rdpd-light-photographs}
TAG=${TAG:-rdpd-light.v17}
REF=${REF:-rdpd-light.v16}
if [ "$REF" = START ]; then  # the shipped tag the run's first phase started from
  REF=$(.venv/bin/python -c "import json, sys; from dualpixel.training.recipe import load_recipe
recipe = load_recipe(json.load(open(sys.argv[1]))['recipe'])
print(recipe.phases[0].init)" "$RUN/recipe.json")
  echo "START: $REF"
fi
CAND=$RUN/ship/$TAG.safetensors
OUT=$RUN/decision
for camera in canon-840 canon-hd canon-stored dslr phone phone-raw phone-close; do
  out=$OUT/$REF/photo-$camera
  [ -f $out/summary.json ] || $DP -q eval --dataset $RUN/data/$camera-test --split test \
      --checkpoint $REF --brightness tied --precision fp32 --no-niqe --figures 0 \
      -o $out > /dev/null
done
echo "$REF on the photographic sets done $(date +%T)"
[ -f $OUT/target-free/target_free.csv ] || $DP -q check-model --input ../shared/data/dp-real-nogt \
  --input ../shared/data/canon-dp-real --input ../shared/data/canon-dp-real-hd \
  --checkpoint $CAND --brightness model --brightness tied --overshoot model --flips off \
  -o $OUT/target-free > $OUT/target-free.log
echo "checks done $(date +%T)"
.venv/bin/python experiments/scripts/decide_photographs.py --run $RUN --tag $TAG --reference $REF "$@"
