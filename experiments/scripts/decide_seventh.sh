#!/usr/bin/env bash
# The seventh decision (recipes/rdpd-light-cameras.yaml, issue #54): every
# number its rule reads, for its candidate and for rdpd-light.v12 as it ships (tied), into
# runs/family6/decision; then experiments/scripts/decide_seventh.py gives the verdict.
# Needs the finished run (runs/family6/ship/rdpd-light.v15.safetensors) and its data. About 35
# minutes on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/../.."
DP=.venv/bin/dualpixel
CAND=${CAND:-runs/family6/ship/rdpd-light.v15.safetensors}
DATA=${DATA:-runs/family6/data}
OUT=${OUT:-runs/family6/decision}
SETS="canon-840-test canon-hd-test canon-stored-test dslr-test phone-test phone-raw-test phone-close-test"
mkdir -p $OUT/synth $OUT/dev
run_eval() {  # checkpoint data split out-folder extra-args...
  local ckpt=$1 data=$2 split=$3 out=$4; shift 4
  [ -f $out/summary.json ] || $DP -q eval --dataset $data $split --checkpoint $ckpt \
      --no-niqe --figures 0 -o $out "$@" > /dev/null
}
for set in $SETS; do  # item 1: as each runs (tied)
  run_eval rdpd-light $DATA/$set "--split test" $OUT/synth/$set/v12 --brightness tied
  run_eval $CAND $DATA/$set "--split test" $OUT/synth/$set/candidate --brightness tied
done
echo synthetic done $(date +%T)
for set in canon-dp-real canon-dp-real-hd; do  # item 4
  run_eval rdpd-light ../shared/data/$set "" $OUT/dev/$set/v12 --brightness tied
  run_eval $CAND ../shared/data/$set "" $OUT/dev/$set/candidate --brightness tied
done
echo dev done $(date +%T)
[ -f $OUT/calibration.json ] || .venv/bin/python experiments/scripts/checks_calibration.py \
  $(for s in $SETS; do echo $DATA/$s; done) --checkpoint rdpd-light --checkpoint $CAND \
  --json $OUT/calibration.json > $OUT/calibration.log  # items 2 and 3's bounds
echo calibration done $(date +%T)
[ -f $OUT/target-free/target_free.csv ] || $DP -q check-model --input ../shared/data/dp-real-nogt \
  --input ../shared/data/canon-dp-real --input ../shared/data/canon-dp-real-hd \
  --checkpoint rdpd-light --checkpoint $CAND --brightness tied --overshoot model --flips off \
  --reference rdpd-light -o $OUT/target-free > $OUT/target-free.log  # item 3
echo checks done $(date +%T)
.venv/bin/python experiments/scripts/decide_seventh.py --candidate $CAND --out $OUT --data $DATA
