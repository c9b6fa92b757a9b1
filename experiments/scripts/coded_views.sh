#!/usr/bin/env bash
# Coded views (issue #54; docs/log/2026-11-28-twelfth-session.md): four held-out sets of the
# family coded as GIF or JPEG frames, each model scored as it ships. Resumable.
#   bash experiments/scripts/coded_views.sh DATA [OUT]   # DATA: the recipe run's data folder
set -euo pipefail
cd "$(dirname "$0")/../.."
DP=".venv/bin/dualpixel -q"
DATA=${1:?the data folder of a recipes/rdpd-light-cameras.yaml run}
OUT=${2:-runs/coded-views}
MODELS="rdpd-light.v15 rdpd-light.v12 rdpd-wide.v2"
for item in canon-840:gif canon-hd:jpeg80 dslr:jpeg80 phone:jpeg80; do
  set_=${item%%:*}; codec=${item##*:}; name=$set_-$codec
  .venv/bin/python experiments/scripts/coded_views.py "$DATA/$set_-test" "$OUT/data/$name" \
    --codec "$codec"
  for model in $MODELS; do
    for copy in "$name:$OUT/data/$name" "$set_-clean:$DATA/$set_-test"; do
      label=${copy%%:*}; data=${copy#*:}
      [ -f "$OUT/eval/$label/$model/summary.json" ] || $DP eval --dataset "$data" --split test \
        --checkpoint "$model" --no-niqe --figures 0 -o "$OUT/eval/$label/$model" > /dev/null
    done
  done
  echo "$name done $(date +%T)"
done
.venv/bin/python experiments/scripts/coded_views_report.py "$OUT"
