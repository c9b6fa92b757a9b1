#!/usr/bin/env bash
# The default adapted to real cameras (issue #74 item 3, after adapt_proof.sh): the Pixel 4 from
# its 20 pairs of dp-real-nogt (camera: its measured PSFs; the views alone do not measure it,
# docs/guide.md), the Canon EOS 5D Mark IV from the dev views at both resolutions (camera from
# the views, targets ignored); both sets of views are GIF / H.264 frames, so the synthetic pairs
# are coded as the default's were (--view-coding h264). Then the dev scenes scored (a floor: the
# Canon adaptation saw their views) and check-model on the real pairs, start and adapted.
# Resumable.
#   bash experiments/scripts/adapt_real.sh [OUT]   # default runs/adapt-real
set -euo pipefail
cd "$(dirname "$0")/../.."
DP=".venv/bin/dualpixel -q"
OUT=${1:-runs/adapt-real}
SHARED=../shared/data
THREADS=${THREADS:-2}
mkdir -p "$OUT"
[ -f "$OUT/pixel4/report.md" ] || $DP adapt "$SHARED/dp-real-nogt" --select 'pixel-gif-0?' \
  --select 'pixel-mp4-0?' --camera pixel4 -o "$OUT/pixel4" --view-coding h264 \
  --threads "$THREADS" --no-progress
[ -f "$OUT/canon/report.md" ] || $DP adapt "$SHARED/canon-dp-real" "$SHARED/canon-dp-real-hd" \
  -o "$OUT/canon" --view-coding h264 --threads "$THREADS" --no-progress
for data in canon-dp-real canon-dp-real-hd; do
  for model in rdpd-light "$OUT/canon/adapted.safetensors"; do
    name=$(basename "$(dirname "$model")")
    [ "$model" = rdpd-light ] && name=rdpd-light
    [ -f "$OUT/eval/$data/$name/summary.json" ] || $DP eval --dataset "$SHARED/$data" \
      --checkpoint "$model" --no-niqe --figures 0 -o "$OUT/eval/$data/$name" > /dev/null
  done
done
[ -f "$OUT/checks/target_free.csv" ] || $DP check-model --input "$SHARED/dp-real-nogt" \
  --checkpoint rdpd-light --checkpoint "$OUT/pixel4/adapted.safetensors" \
  --checkpoint "$OUT/canon/adapted.safetensors" -o "$OUT/checks" > "$OUT/checks.log"
.venv/bin/python - "$OUT" <<'PY'
import sys
from pathlib import Path
sys.path.insert(0, "experiments/scripts")
from decide_seventh import gain
out = Path(sys.argv[1])
for data in ("canon-dp-real", "canon-dp-real-hd"):
    print(data, {m: round(gain(out / "eval" / data / m), 3) for m in ("rdpd-light", "canon")})
PY
