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
#                               exact and its frames per second, then `training`
#   training                    training iterations per second on written and on-the-fly data
#                               (6, 12 and 15 loader processes; rendering on the device, in the
#                               training process or by 15 loader processes), and a
#                               crop's cost to one host core under cProfile (~4 minutes)
#   tests                       issue #76's CUDA-path tests (tests/gpu) into $OUT/tests_gpu.txt
#   profile                     where issue #71's GPU synthesis spends its time: one batched call
#                               at 1920x1080 and at 840x560, and on-the-fly training rendered on
#                               the device (bench_synthesis.py --profile) into $OUT (~2 minutes)
#   checks                      tests and synthesis in one call (5 files, ~7 minutes): what a
#                               lease without a training run should do first
#
# Photographic recipes (rdpd-light-photographs*.yaml) read ../shared/data/photographs (61 MB),
# which does not travel: a call sends the repository alone, at most 64 MiB with what it carries,
# and the tracked files take 55 MiB of that (44 MB the three shipped weights; 2026-12-03). So the
# photographs go in parts, one a call, onto a machine kept warm (it goes back ~30 s after a call):
#   pack [BYTES]                here: the photographs in parts under .photos/ (ignored), each at
#                               most BYTES (default: what the tree leaves of 64 MiB, less 2 MiB)
#   unpack N K                  there: part N of K (carry .photos/N) into ../shared/data/
#                               photographs; part K checks that every photograph arrived
# Calls 1..K-1 `unpack N K`, each at once after the last; call K `unpack K K && start ...`.
# With 55 MiB of tree that is 9 parts; slim the tree first (about 2 parts), unslim after:
#   slim [TAG...]               here: the shipped weights other than TAG... (the tags the lease's
#                               recipe starts from; none for a recipe from nothing) stop
#                               travelling: untracked in the index and ignored in
#                               .git/info/exclude, the files left in place; a pre-commit hook
#                               refuses commits until `unslim`, which would delete them
#   unslim                      here: the weights tracked again, the index and exclude as before
# e.g. device run: bash experiments/scripts/gpu_lease.sh start experiments/recipes/rdpd-canon-full.yaml runs/reproduce/rdpd-canon-full
set -euo pipefail
command=${1:?start, wait, stop, collect, kit, figures, synthesis, training, tests, profile, checks, pack, unpack, slim or unslim}; shift

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
  "$0" training
  ;;
training)  # issue #71: training iterations per second, long enough that the loader's start is
  # a small part (240 iterations), at 6, 12 and 15 loader processes; one process rendering
  # in the training process on the CPU under cProfile: what a crop costs one of these cores
  : "${OUT:?set OUT to the device tool output folder}"
  bench() { PYTHONPATH=src python3 benchmarks/bench_synthesis.py --training --device cuda "$@" \
              2>&1 | grep -v '^{'; }
  { bench --data written,fly --iterations 240 --loader-workers 12
    bench --data fly-device --iterations 40
    bench --data fly-device --iterations 40 --cache
    bench --data fly-device --iterations 240 --loader-workers 15  # each renders on the GPU
    bench --data fly --iterations 240 --loader-workers 15
    bench --data fly --iterations 240 --loader-workers 15 --cache  # as a frame store serves
  } | tee "$OUT/bench_training_cuda.txt"
  bench --data fly --iterations 12 --loader-workers 0 --profile \
    | tee "$OUT/profile_training_loader.txt"
  bench --data fly --iterations 240 --loader-workers 6 | tee -a "$OUT/bench_training_cuda.txt"
  ;;
tests)  # issue #76: the CUDA paths' tests (tests/gpu), their report into $OUT (~2 minutes)
  : "${OUT:?set OUT to the device tool output folder}"
  python3 -c "import pytest" 2>/dev/null || python3 -m pip install --quiet pytest
  PYTHONPATH=src python3 -m pytest -q -p no:cacheprovider tests/gpu 2>&1 | tee "$OUT/tests_gpu.txt"
  ;;
profile)  # issue #71: where the batched renderer and device-rendered training spend their time
  : "${OUT:?set OUT to the device tool output folder}"
  for size in "1920 1080" "840 560"; do
    set -- $size
    PYTHONPATH=src python3 benchmarks/bench_synthesis.py --batched --profile --device cuda \
      --batch 16 --width "$1" --height "$2" 2>&1 | tee "$OUT/profile_batched_$1.txt"
  done
  PYTHONPATH=src python3 benchmarks/bench_synthesis.py --training --profile --device cuda \
    --data fly-device --iterations 20 2>&1 | grep -v '^{' | tee "$OUT/profile_training_cuda.txt"
  ;;
checks)  # the GPU checks of issues #71 and #76 in one call: one machine start for all
  failed=""
  for step in tests synthesis; do  # each runs whatever the one before gave
    "$0" "$step" || failed="$failed $step"
  done
  [ -z "$failed" ] || { echo "failed:$failed" >&2; exit 1; }
  ;;
pack)  # here: the photographs in parts that travel one a call (see the header)
  photos=${PHOTOS:-../shared/data/photographs}
  [ -d "$photos/train" ] || { echo "no $photos/train: set PHOTOS to the photographs" >&2; exit 1; }
  tree=$(git ls-files -co --exclude-standard -z | grep -zv '^\.photos/' | xargs -0 stat -c %s \
         | awk '{s += $1} END {print s}')
  budget=${1:-$(( (64 << 20) - tree - (2 << 20) ))}
  if (( budget < (1 << 20) )); then
    echo "the tree takes $((tree >> 20)) MiB of 64: no room to carry photographs" >&2; exit 1
  fi
  rm -rf .photos
  part=1 used=0
  for split in train validation; do
    for file in "$photos/$split"/*; do
      size=$(stat -c %s "$file")
      if (( used > 0 && used + size > budget )); then part=$((part + 1)); used=0; fi
      mkdir -p ".photos/$part/$split"
      cp "$file" ".photos/$part/$split/"
      used=$((used + size))
    done
  done
  counts="$(ls "$photos/train" | wc -l) $(ls "$photos/validation" | wc -l)"
  for n in $(seq 1 $part); do echo "$counts" > ".photos/$n/expected"; done
  mib() { awk -v b="$1" 'BEGIN {printf "%.1f", b / 1048576}'; }
  echo "tree $(mib "$tree") MiB; $counts photographs in $part parts of at most" \
       "$(mib "$budget") MiB: .photos/1 .. .photos/$part (carry one a call)"
  ;;
unpack)  # on the device: part N of K into ../shared/data/photographs
  n=$1 parts=$2 into=../shared/data/photographs
  [ -d ".photos/$n" ] || { echo "part .photos/$n did not travel (carry it)" >&2; exit 1; }
  for split in train validation; do
    mkdir -p "$into/$split"
    [ -d ".photos/$n/$split" ] && cp ".photos/$n/$split"/* "$into/$split/"
  done
  read -r train validation < ".photos/$n/expected"
  have="$(ls "$into/train" | wc -l) $(ls "$into/validation" | wc -l)"
  echo "part $n of $parts: photographs here $have of $train $validation"
  if [ "$n" = "$parts" ] && [ "$have" != "$train $validation" ]; then
    echo "photographs missing: the machine was given back between parts; unpack 1..$parts" \
         "again" >&2
    exit 1
  fi
  ;;
slim)  # here: only the weights the lease needs travel (see the header)
  marker=$(git rev-parse --git-path dualpixel-slim)
  exclude=$(git rev-parse --git-path info/exclude)
  hook=$(git rev-parse --git-path hooks)/pre-commit
  [ -f "$marker" ] && { echo "already slim (unslim first): $(cat "$marker" | tr '\n' ' ')" >&2; exit 1; }
  if [ -n "$(git status --porcelain -- src/dualpixel/weights)" ]; then
    echo "src/dualpixel/weights has changes: commit or undo them first" >&2; exit 1
  fi
  if [ -e "$hook" ] && ! grep -q dualpixel-slim "$hook"; then
    echo "$hook exists and is not ours: slim would replace it" >&2; exit 1
  fi
  for tag in "$@"; do
    [ -f "src/dualpixel/weights/$tag.safetensors" ] || { echo "no shipped weights $tag" >&2; exit 1; }
  done
  : > "$marker"
  for path in $(git ls-files 'src/dualpixel/weights/*.safetensors'); do
    tag=$(basename "$path" .safetensors)
    [[ " $* " == *" $tag "* ]] && continue
    git rm -q --cached -- "$path"
    echo "/$path" >> "$exclude"
    echo "$path" >> "$marker"
  done
  mkdir -p "$(dirname "$hook")"
  cat > "$hook" <<'HOOK'
#!/bin/sh
# dualpixel-slim: gpu_lease.sh slim untracked shipped weights for a lease; a commit now would
# delete them from the repository. Run `bash experiments/scripts/gpu_lease.sh unslim` first.
if [ -f "$(git rev-parse --git-path dualpixel-slim)" ]; then
  echo "refused: the tree is slimmed for a GPU lease (gpu_lease.sh unslim first)" >&2
  exit 1
fi
HOOK
  chmod +x "$hook"
  tree=$(git ls-files -co --exclude-standard -z | xargs -0 stat -c %s | awk '{s += $1} END {print s}')
  echo "slim: $(wc -l < "$marker") weight file(s) stay here; the tree that travels:" \
       "$(awk -v b="$tree" 'BEGIN {printf "%.1f", b / 1048576}') MiB"
  ;;
unslim)  # here: the tree as it was before `slim`
  marker=$(git rev-parse --git-path dualpixel-slim)
  exclude=$(git rev-parse --git-path info/exclude)
  [ -f "$marker" ] || { echo "not slim: nothing to undo"; exit 0; }
  while read -r path; do
    git reset -q -- "$path"
    grep -vxF "/$path" "$exclude" > "$exclude.new" || true
    mv "$exclude.new" "$exclude"
  done < "$marker"
  rm -f "$marker"
  echo "unslim: $(git ls-files 'src/dualpixel/weights/*.safetensors' | wc -l) weight file(s) tracked"
  ;;
*)
  echo "unknown command: $command (start, wait, stop, collect, kit, figures, synthesis," \
       "training, tests, profile, checks, pack, unpack, slim or unslim)" >&2
  exit 2
  ;;
esac
