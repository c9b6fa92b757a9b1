#!/usr/bin/env bash
# A long `dualpixel reproduce` on a lent GPU machine (the `device` tool), across several calls.
#
# The machine is given back ~30 s after a call ends, and with it the run folder, so the job runs
# in the background and every call stays busy waiting on it; call again as soon as one returns.
# The device's python3 has torch; the project runs from the sent tree (PYTHONPATH=src).
#
#   start RECIPE RUN [SECONDS]  start the run in the background (unless it runs), then `wait`;
#                               WORKERS, LOADER_WORKERS, FRAME_STORE: its machine settings
#   wait RUN [SECONDS]          wait up to SECONDS (default 540) while it runs; print progress
#   stop RECIPE RUN             end a run still going near the end of the budget and export its
#                               last finished epoch (EMA weights) as RUN/ship/NAME.safetensors
#                               (float16, the recipe's `ship` name); the evaluation is not run
#   collect RUN NAME            put RUN/ship/NAME.safetensors into $OUT as 15 MiB parts, with its
#                               sha256 and the log's tail (join here: cat NAME.part* > NAME.safetensors)
#   kit RUN PHASE               put what `dualpixel release` needs of RUN into $OUT as 15 MiB parts
#                               of one tar (records, histories, evaluations, the export and the
#                               shipped PHASE's last.safetensors; no data, no resume states):
#                               cat RUN-kit.tar.part* | tar xf - -C runs/ here
#   figures                     the GPU figures of issue #36 into $OUT: bench_inference.py (and a
#                               profile of its default and fp32 passes) and bench_synthesis.py
#                               (render only) on cuda, nvidia-smi (~5 minutes);
#                               not while a run trains (they would share the GPU)
#   synthesis                   issue #71's GPU figures into $OUT: the batched renderer against
#                               exact and its frames per second, training iterations per second
#                               on written and on-the-fly data (loader and device rendering)
#   tests                       issue #76's CUDA-path tests (tests/gpu) into $OUT/tests_gpu.txt
#
# Photographic recipes (rdpd-light-photographs*.yaml) read ../shared/data/photographs (54 MB for
# train/), which does not travel: a call sends the repository alone, at most 64 MiB with its
# tracked files (57 MB on 2026-12-03, 44 MB of them the three shipped weights; a fourth would put
# the tree itself over the limit). Such a run needs fewer weights in the package first, then the
# photographs carried in parts (an ignored folder each call, copied on the warm machine to
# ../shared/data/photographs) before `start`; a run without them stops at its first data step.
# e.g. device run: bash experiments/scripts/gpu_lease.sh start experiments/recipes/rdpd-canon-full.yaml runs/reproduce/rdpd-canon-full
set -euo pipefail
command=${1:?start, wait, stop, collect, kit, figures, synthesis or tests}; shift

running() { [ -f "$1.pid" ] && kill -0 "$(cat "$1.pid")" 2>/dev/null; }

case $command in
start)
  recipe=$1 run=$2 seconds=${3:-540}
  mkdir -p "$(dirname "$run")"
  if running "$run"; then
    echo "already running: $run"
  else
    rm -f "$run.rc"
    # its own session and process group (the pid file holds its id): `stop` ends the run with
    # every loader process it forked, and a call's end does not kill it (the machine stays
    # warm ~30 s, so it goes on only until then unless the next call comes)
    # the machine's settings (data processes, loader processes, the shared frame store)
    setsid bash -c 'PYTHONPATH=src python3 -m dualpixel reproduce "$1" --output "$2" \
        --workers "$3" --loader-workers "$4" --frame-store "$5" --no-progress; \
        echo $? > "$2.rc"' _ "$recipe" "$run" "${WORKERS:-14}" "${LOADER_WORKERS:-12}" \
        "${FRAME_STORE:-runs/frame-store}" >> "$run.log" 2>&1 < /dev/null &
    echo $! > "$run.pid"
    echo "started: $run (log $run.log)"
  fi
  exec "$0" wait "$run" "$seconds"
  ;;
wait)
  run=$1 seconds=${2:-540}
  end=$((SECONDS + seconds))
  while running "$run" && [ ! -f "$run.rc" ] && [ $SECONDS -lt $end ]; do sleep 5; done
  tail -n 8 "$run.log" || true
  nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv,noheader 2>/dev/null || true
  if [ -f "$run.rc" ]; then
    echo "finished: exit status $(cat "$run.rc")"
  elif running "$run"; then
    echo "still running: call wait again now"
  else  # killed, or a fresh machine without the run: start again (reproduce resumes)
    echo "not running and no exit status: start it again" >&2
    exit 1
  fi
  ;;
stop)
  recipe=$1 run=$2
  if ! running "$run" || [ -f "$run.rc" ]; then
    echo "not running: $run (nothing to stop)"
    exit 0
  fi
  group=$(cat "$run.pid")
  kill -TERM -- "-$group" 2>/dev/null || true
  sleep 5
  kill -KILL -- "-$group" 2>/dev/null || true
  echo "stopped: $run"
  PYTHONPATH=src python3 - "$recipe" "$run" <<'PY'
import sys
from pathlib import Path
from dualpixel.training.recipe import load_recipe, ship_phase
recipe, output = load_recipe(sys.argv[1]), Path(sys.argv[2])
phase = recipe.shipped_phase
folder = recipe.phase_folder(output, recipe.phase_index(phase))
print("exported", ship_phase(recipe, folder, output, phase, {"stopped_early": True}))
PY
  ;;
collect)
  run=$1 name=$2
  weights=$run/ship/$name.safetensors
  [ -f "$weights" ] || { echo "no $weights" >&2; exit 1; }
  : "${OUT:?set OUT to the device tool output folder}"
  split -b 15M -d "$weights" "$OUT/$name.part"
  (cd "$(dirname "$weights")" && sha256sum "$name.safetensors") > "$OUT/$name.sha256"
  tail -n 40 "$run.log" > "$OUT/$name.log"
  ls -l "$OUT"
  ;;
kit)
  run=$1 phase=$2
  : "${OUT:?set OUT to the device tool output folder}"
  (cd "$(dirname "$run")" && find "$(basename "$run")" -type f ! -path "*/data/*" ! -name "*.pt" \
      ! -name "best.safetensors" ! -path "*/tensorboard/*" \
      \( ! -name last.safetensors -o -path "*/phases/$phase/*" \) | sort \
      | tar cf - -T -) | split -b 15M -d - "$OUT/$(basename "$run")-kit.tar.part"
  ls -l "$OUT"
  ;;
figures)
  : "${OUT:?set OUT to the device tool output folder}"
  nvidia-smi > "$OUT/nvidia-smi.txt" 2>&1 || true
  PYTHONPATH=src python3 benchmarks/bench_inference.py --device cuda 2>&1 \
    | tee "$OUT/bench_inference_cuda.txt"
  for case in default fp32; do  # where a CUDA pass spends its time (host or device)
    PYTHONPATH=src python3 benchmarks/bench_inference.py --device cuda --profile $case 2>&1
  done > "$OUT/profile_inference_cuda.txt"
  PYTHONPATH=src python3 benchmarks/bench_synthesis.py --device cuda --no-baseline 2>&1 \
    | tee "$OUT/bench_synthesis_cuda.txt"
  ;;
synthesis)  # issue #71's GPU figures: the batched renderer and on-the-fly training (~6 minutes)
  : "${OUT:?set OUT to the device tool output folder}"
  nvidia-smi > "$OUT/nvidia-smi.txt" 2>&1 || true
  PYTHONPATH=src python3 benchmarks/bench_synthesis.py --batched --device cuda --batch 16 \
    --repeat 3 2>&1 | tee "$OUT/bench_batched_cuda.txt"
  PYTHONPATH=src python3 benchmarks/bench_synthesis.py --training --device cuda --iterations 40 \
    --loader-workers 12 2>&1 | grep -v '^{' | tee "$OUT/bench_training_cuda.txt"
  ;;
tests)  # issue #76: the CUDA paths' tests (tests/gpu), their report into $OUT (~2 minutes)
  : "${OUT:?set OUT to the device tool output folder}"
  python3 -c "import pytest" 2>/dev/null || python3 -m pip install --quiet pytest
  PYTHONPATH=src python3 -m pytest -q -p no:cacheprovider tests/gpu 2>&1 | tee "$OUT/tests_gpu.txt"
  ;;
*)
  echo "unknown command: $command (start, wait, stop, collect, kit, figures, synthesis or" \
       "tests)" >&2
  exit 2
  ;;
esac
