#!/usr/bin/env bash
# The GPU node's figures (docs/scaling.md says how they are read; docs/benchmarks.md has them).
#
#   bash benchmarks/gpu_node.sh throughput OUT   the node's first call, ~5.5 minutes: the learner's
#                                             step paths side by side (the host-stepped step with
#                                             compiled losses and the whole step in one CUDA graph,
#                                             alternating), then
#                                             30-s navigation trainings with 2, 4, 8 and 14 workers
#                                             x 4 envs and the GPU learner (batch 128 per worker),
#                                             and 8 workers with the CPU learner beside.
#   bash benchmarks/gpu_node.sh learning OUT [S] [CONFIG]  the second call: one navigation
#                                             training of the node recipe (CONFIG, by default
#                                             experiments/configs/navigation-node.json; the
#                                             variant navigation-node-spi128.json asks the learner
#                                             for 4x the samples per insert) for S seconds (360),
#                                             a policy snapshot a minute, the run packed as
#                                             OUT/<config's name>.tar.gz to be scored here
#                                             (experiments/peers.py evaluate) on the 2-core seeds'
#                                             100 episodes.
#   bash benchmarks/gpu_node.sh learner OUT   the learner alone on CUDA, batch 256 to 16,384:
#                                             eager, the CPU learner with 1-14 threads, 8 SGD steps
#                                             per sample, compiled (CUDA graphs), bf16 (<= 9 min).
#   bash benchmarks/gpu_node.sh versus OUT OTHER   the eager learner of this tree and of OTHER
#                                             (e.g. `git archive COMMIT robogym_ray | tar -x
#                                             -C .before`), alternating, twice; then the switches.
#   bash benchmarks/gpu_node.sh profile OUT  the eager and compiled learner, each figure with a
#                                             profile: wall, kernel and host time.
#
# The node has torch and no network, and lacks ray, pybullet and gymnasium: `bash
# benchmarks/device_kit.sh` builds them here into .device-kit/ (git-ignored), which each call
# carries (`carry: [".device-kit"]`); this script installs it into /tmp/robogym-kit when an
# import fails (a warm node keeps it for the next call). The repository's root goes on
# PYTHONPATH: the project is not installed there. Every part writes one JSON line per figure as
# it comes and its errors to OUT/errors.log, each step with its own time limit, and the steps
# after a failed one still run (a node's time is short: one failure must not cost the figures
# after it).
#
# Rehearse here before spending device time (no GPU, every part and switch exercised, short):
#   GPU_NODE_DEVICE=cpu GPU_NODE_SECONDS=1 GPU_NODE_TRAIN_S=15 GPU_NODE_WORKERS="1 2" \
#       GPU_NODE_CPUS=16 bash benchmarks/gpu_node.sh throughput /tmp/rehearsal
#   GPU_NODE_DEVICE=cpu GPU_NODE_CPUS=16 GPU_NODE_LEARN_WORKERS=2 \
#       bash benchmarks/gpu_node.sh learning /tmp/rehearsal-learning 60
# (docs/benchmarks.md has the whole rehearsal: a bare python3.12 venv, the kit, no network.)
set -euo pipefail
part=${1:?throughput, learning, learner, versus or profile}
out=${2:?output folder}
root=$(cd "$(dirname "$0")/.." && pwd)
py=$(command -v "${PYTHON:-python3}") # absolute: the import check below runs from /
mkdir -p "$out"
export PYTHONUNBUFFERED=1 RAY_AUTH_MODE=disabled
device=${GPU_NODE_DEVICE:-cuda}
seconds=${GPU_NODE_SECONDS:-5}
# Ray's CPUs: the node's cores. A rehearsal on a small machine names the node's 16, so every run
# reserves what it will there (the cores oversubscribed, which only slows it).
cpus=${GPU_NODE_CPUS:-$(nproc)}
if ! (cd / && "$py" -c "import ray, pybullet, gymnasium") 2>/dev/null; then
  bash "$root/benchmarks/device_kit.sh" install /tmp/robogym-kit
  export PYTHONPATH=/tmp/robogym-kit${PYTHONPATH:+:$PYTHONPATH}
fi
# This checkout, installed or not (a script's own folder, not the current one, is on its path).
export PYTHONPATH=$root${PYTHONPATH:+:$PYTHONPATH}
(cd / && "$py" -c "import robogym_ray, ray, pybullet, gymnasium") # fails here, in seconds
{
  if [ "$device" = cuda ]; then
    nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader
  fi
  "$py" -c "import torch, ray; print('torch', torch.__version__, 'ray', ray.__version__)"
  echo "cores $(nproc), $(grep -m1 'model name' /proc/cpuinfo), load $(cut -d' ' -f1-3 /proc/loadavg)"
} | tee "$out/device.txt"

# One step of the learner's figures: its own time limit, its errors kept, and the steps after
# it run whatever became of it (as above).
measure() {
  local limit=$1 name=$2
  shift 2
  echo "== $name" | tee -a "$out/errors.log"
  timeout "$limit" "$py" "$root/benchmarks/learner_capacity.py" alone "$@" \
    2>>"$out/errors.log" | tee -a "$out/learner.jsonl" ||
    echo "== $name: stopped, exit ${PIPESTATUS[0]}" | tee -a "$out/errors.log"
}
all=(--batches 256 1024 4096 16384 --seconds "$seconds")
# The GPU path's switches, one measure each: blocks of SGD steps, compiled, compiled with bf16.
switches() {
  measure 50 "eager, 8 SGD steps per sample" --device "$device" --batches 1024 4096 16384 \
    --seconds "$seconds" --sgd-steps 8
  measure 180 compiled --device "$device" "${all[@]}" --warmup 30 --compile reduce-overhead
  measure 110 "compiled, bf16, 8 SGD steps" --device "$device" --batches 4096 16384 \
    --seconds "$seconds" --warmup 30 --compile reduce-overhead --bf16 --sgd-steps 8
}
case "$part" in
learner)
  measure 75 eager --device "$device" "${all[@]}"
  # The CPU learner on this node's cores: its threads beyond the 2 cores of the machine
  # where the model's CPU figures were measured.
  measure 80 "CPU threads" --device cpu --batches 1024 --threads 1 2 4 8 14 --seconds 4
  measure 60 "CPU threads, batch 4096" --device cpu --batches 4096 --threads 1 8 14 --seconds 4
  switches
  ;;
versus)
  # This tree's learner against another's on one machine, alternating (ratios side by side).
  other=${3:?the other checkout: a folder holding the robogym_ray/ of another commit}
  for round in 1 2; do
    for tree in "$other" "$root"; do
      PYTHONPATH=$tree:$PYTHONPATH measure 60 "eager, $tree, round $round" --device "$device" \
        "${all[@]}"
    done
  done
  switches
  ;;
profile)
  # Where a step's time goes (wall, kernel and host time per step), eager and compiled.
  measure 50 "eager, profiled" --device "$device" --batches 1024 --seconds "$seconds" --profile 50
  measure 150 "compiled, profiled" --device "$device" "${all[@]}" --warmup 30 \
    --compile reduce-overhead --profile 50
  ;;
throughput)
  # The whole step's tests, the CUDA graph's among them (CI has no GPU): seconds, and they say
  # whether the figures below measure a correct step.
  echo "== the whole step's tests" | tee -a "$out/errors.log"
  (cd "$root" && timeout 120 "$py" -m pytest -q -p no:cacheprovider -o addopts="" \
    tests/learner/test_whole_step.py) >"$out/pytest.txt" 2>&1 ||
    echo "== tests: failed (pytest.txt)" | tee -a "$out/errors.log"
  tail -3 "$out/pytest.txt"
  # The host-stepped step with compiled losses and the whole step, side by side at batch 256 (the
  # goal's) and at the node recipe's 1,792, in calls of 4 steps (what a coupled insert owes at 14
  # workers).
  echo "== learner paths" | tee -a "$out/errors.log"
  timeout 150 "$py" "$root/benchmarks/learner_capacity.py" paths --paths compiled whole \
    --device "$device" --batches 256 1792 --rounds 3 --seconds "$seconds" --warmup 30 \
    --call-steps 4 2>>"$out/errors.log" | tee -a "$out/learner.jsonl" ||
    echo "== learner paths: stopped, exit ${PIPESTATUS[0]}" | tee -a "$out/errors.log"
  # The trainings take the whole step where it ran above, else the compiled losses.
  if grep -q '"path": "whole", "round": 0' "$out/learner.jsonl" 2>/dev/null; then
    gpu_d4pg='{"whole_step": "on"}'
  else
    gpu_d4pg='{"compile": "reduce-overhead"}'
  fi
  train_s=${GPU_NODE_TRAIN_S:-30}
  for workers in ${GPU_NODE_WORKERS:-2 4 8 14}; do
    echo "== training, $workers workers, GPU learner $gpu_d4pg" | tee -a "$out/errors.log"
    timeout $((train_s + 60)) "$py" "$root/benchmarks/scaling.py" train --task navigation \
      --workers "$workers" --envs 4 --batch $((128 * workers)) --samples-per-insert 32 \
      --wall-s "$train_s" --repeats 1 --num-cpus "$cpus" --learner-cpus 1 --worker-cpus 1 \
      --d4pg "$gpu_d4pg" 2>>"$out/errors.log" | tee -a "$out/train.jsonl" ||
      echo "== training: stopped, exit ${PIPESTATUS[0]}" | tee -a "$out/errors.log"
  done
  echo "== training, 8 workers, CPU learner" | tee -a "$out/errors.log"
  timeout $((train_s + 60)) "$py" "$root/benchmarks/scaling.py" train --task navigation \
    --workers 8 --envs 4 --batch 1024 --samples-per-insert 32 --wall-s "$train_s" --repeats 1 \
    --num-cpus "$cpus" --learner-cpus 4 --worker-cpus 1 --learner-gpus 0 \
    --d4pg '{"device": "cpu"}' 2>>"$out/errors.log" | tee -a "$out/train.jsonl" ||
    echo "== training: stopped, exit ${PIPESTATUS[0]}" | tee -a "$out/errors.log"
  ;;
learning)
  # The node recipe for S seconds (the config's 1,000,000 steps lifted: the node passes them
  # in 2-3 minutes); its run folder (summary, snapshots, metrics) comes back packed.
  wall=${3:-360}
  config=${4:-$root/experiments/configs/navigation-node.json}
  config=$(cd "$(dirname "$config")" && pwd)/$(basename "$config") # absolute: the run starts in /
  name=$(basename "$config" .json)
  runs=/tmp/node-runs
  rm -rf "${runs:?}/$name-seed0"
  # A rehearsal on a small machine may run fewer of the recipe's workers (GPU_NODE_LEARN_WORKERS).
  extra=()
  [ -z "${GPU_NODE_LEARN_WORKERS:-}" ] || extra=(--workers "$GPU_NODE_LEARN_WORKERS")
  echo "== learning, $name, $wall s, load $(cut -d' ' -f1-3 /proc/loadavg)" |
    tee -a "$out/errors.log"
  (cd / && timeout $((wall + 90)) "$py" -m robogym_ray.cli train --config "$config" \
    --max-wall-s "$wall" --total-steps 1000000000 --logdir "$runs" --run-name "$name-seed0" \
    --seed 0 --no-progress --num-cpus "$cpus" "${extra[@]}") 2>&1 | tail -40 >>"$out/errors.log" ||
    echo "== learning: stopped" | tee -a "$out/errors.log"
  cp "$runs/$name-seed0/summary.json" "$out/$name.summary.json" 2>/dev/null || true
  tar -czf "$out/$name.tar.gz" -C "$runs" --exclude='*.replay.npz' "$name-seed0" ||
    echo "== learning: nothing to pack" | tee -a "$out/errors.log"
  ls -l "$out"
  ;;
*) echo "unknown part $part: throughput, learning, learner, versus or profile" >&2; exit 2 ;;
esac
