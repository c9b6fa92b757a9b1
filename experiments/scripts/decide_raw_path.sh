#!/usr/bin/env bash
# The raw-path decision (experiments/recipes/rdpd-light-raw-path.yaml, issue #54): what its rule
# reads for rdpd-light.v15 as it ships (tied), beside the candidate's own evaluation that
# `dualpixel reproduce` wrote (RUN/eval), then experiments/scripts/decide_raw_path.py gives the
# verdict. About 30 minutes on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/../.."
DP=.venv/bin/dualpixel
RUN=${RUN:-runs/rawpath}
CAND=${CAND:-$RUN/ship/rdpd-light-raw-path.v1.safetensors}
OUT=${OUT:-$RUN/decision}
LEVELS="--encoding linear --black-level 15.9375 --white-level 255"
mkdir -p $OUT
run_eval() {  # data split out-folder extra-args...
  local data=$1 split=$2 out=$3; shift 3
  [ -f $out/summary.json ] || $DP -q eval --dataset $data $split --checkpoint rdpd-light.v15 \
      --brightness tied --no-niqe --figures 0 -o $out "$@" > /dev/null
}
for set in canon-840 canon-hd canon-stored dslr phone phone-raw phone-close; do  # item 1
  run_eval $RUN/data/$set-test "--split test" $OUT/v15/$set
done
run_eval $RUN/data/phone-raw-test "--split test" $OUT/v15/phone-raw-linear $LEVELS
echo synthetic done $(date +%T)
for set in canon-dp-real canon-dp-real-hd; do  # item 3
  run_eval ../shared/data/$set "" $OUT/v15/$set
done
echo dev done $(date +%T)
[ -f $OUT/target-free/target_free.csv ] || $DP -q check-model --input ../shared/data/dp-real-nogt \
  --input ../shared/data/canon-dp-real --input ../shared/data/canon-dp-real-hd \
  --checkpoint rdpd-light.v15 --checkpoint $CAND --brightness tied --overshoot model \
  --flips off --reference rdpd-light.v15 -o $OUT/target-free > $OUT/target-free.log
echo checks done $(date +%T)
.venv/bin/python experiments/scripts/decide_raw_path.py --run $RUN --out $OUT
