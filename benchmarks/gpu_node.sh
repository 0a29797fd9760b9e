#!/usr/bin/env bash
# Issue 42's GPU figures on a node with one GPU (docs/scaling.md says how they are read).
#
#   bash benchmarks/gpu_node.sh learner OUT   the learner alone on CUDA, batch 256 to 16,384:
#                                             eager, the CPU learner with 1-14 threads on the
#                                             node's cores, eager with 8 SGD steps per sample,
#                                             compiled (CUDA graphs), then bf16 with 8 SGD steps;
#                                             at most 9 minutes (each part has its limit); a
#                                             line of JSON per figure as it comes, errors in
#                                             OUT/errors.log.
#   bash benchmarks/gpu_node.sh versus OUT OTHER   the eager learner of this tree and of OTHER
#                                             (e.g. `git archive COMMIT robogym_ray | tar -x
#                                             -C .before`), alternating, twice; then this
#                                             tree's 8-SGD-step, compiled and bf16 figures.
#   bash benchmarks/gpu_node.sh profile OUT  the eager and compiled learner again, each figure
#                                             with a profile: wall, kernel and host time.
#   bash benchmarks/gpu_node.sh train OUT     90-s navigation trainings with 2, 4, 8 and 14
#                                             workers and the GPU learner, then 8 workers with
#                                             the CPU learner (one thread per learner CPU);
#                                             about 10 minutes; needs the project installed.
#   bash benchmarks/gpu_node.sh wheels        here, with a network: the wheels the learner part
#                                             needs on a machine that has only torch (below).
#
# The learner part needs torch, numpy and gymnasium (importing robogym_ray registers its env
# ids), not the project installed: the repository's root goes on PYTHONPATH. A machine with
# torch and no network - this workplace's device machines run Python 3.12 with torch and no
# gymnasium - gets gymnasium from .device-wheels/ (git-ignored, 0.5 MB), which `wheels` fills
# and the device call carries. The train part cannot run on those machines: ray's wheel (79 MB)
# is larger than one call carries (64 MiB) and pybullet has no wheel for Python 3.12. It is for
# a GPU node of one's own, with `pip install -e .` done.
#
# Rehearse the learner part here before spending device time (no GPU, every switch exercised):
#   GPU_NODE_DEVICE=cpu GPU_NODE_SECONDS=1 bash benchmarks/gpu_node.sh learner /tmp/rehearsal
set -euo pipefail
part=${1:?learner, train or wheels}
root=$(cd "$(dirname "$0")/.." && pwd)
wheels="$root/.device-wheels"
py=$(command -v "${PYTHON:-python3}") # absolute: the import check below runs from /

if [ "$part" = wheels ]; then
  # The device's interpreter, not this one: Python 3.12 on manylinux x86-64.
  "$py" -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 \
    --implementation cp --platform manylinux2014_x86_64 -d "$wheels" \
    gymnasium==1.4.0 farama-notifications==0.0.6
  ls -l "$wheels"
  exit 0
fi

out=${2:?output folder}
mkdir -p "$out"
export PYTHONUNBUFFERED=1 RAY_AUTH_MODE=disabled
device=${GPU_NODE_DEVICE:-cuda}
seconds=${GPU_NODE_SECONDS:-5}
if ! "$py" -c "import gymnasium" 2>/dev/null; then
  if ! compgen -G "$wheels/*.whl" >/dev/null; then
    echo "no gymnasium here and no wheels in $wheels: run 'bash $0 wheels' where pip works," \
      "and carry .device-wheels with the call" >&2
    exit 2
  fi
  "$py" -m pip install -q --no-index --no-deps --no-compile --target /tmp/gpu-node-site \
    "$wheels"/*.whl
  export PYTHONPATH=/tmp/gpu-node-site${PYTHONPATH:+:$PYTHONPATH}
fi
# This checkout, installed or not (a script's own folder, not the current one, is on its path).
export PYTHONPATH=$root${PYTHONPATH:+:$PYTHONPATH}
(cd / && "$py" -c "import robogym_ray") # fails here, in seconds, not after a machine's start
{
  if [ "$device" = cuda ]; then
    nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader
  fi
  "$py" -c "import torch; print('torch', torch.__version__)"
  echo "cores $(nproc), $(grep -m1 'model name' /proc/cpuinfo)"
} | tee "$out/device.txt"

# One part of the learner's figures: its own time limit, its errors kept, and the parts after
# it run whatever became of it (a device lease allows one try).
part() {
  local limit=$1 name=$2
  shift 2
  echo "== $name" | tee -a "$out/errors.log"
  timeout "$limit" "$py" "$root/benchmarks/learner_capacity.py" alone "$@" \
    2>>"$out/errors.log" | tee -a "$out/learner.jsonl" ||
    echo "== $name: stopped, exit ${PIPESTATUS[0]}" | tee -a "$out/errors.log"
}
all=(--batches 256 1024 4096 16384 --seconds "$seconds")
# The GPU path's switches, one part each: blocks of SGD steps, compiled, compiled with bf16.
switches() {
  part 50 "eager, 8 SGD steps per sample" --device "$device" --batches 1024 4096 16384 \
    --seconds "$seconds" --sgd-steps 8
  part 180 compiled --device "$device" "${all[@]}" --warmup 30 --compile reduce-overhead
  part 110 "compiled, bf16, 8 SGD steps" --device "$device" --batches 4096 16384 \
    --seconds "$seconds" --warmup 30 --compile reduce-overhead --bf16 --sgd-steps 8
}
case "$part" in
learner)
  part 75 eager --device "$device" "${all[@]}"
  # The CPU learner on this node's cores: its threads beyond the 2 cores of the machine
  # where the model's CPU figures were measured.
  part 80 "CPU threads" --device cpu --batches 1024 --threads 1 2 4 8 14 --seconds 4
  part 60 "CPU threads, batch 4096" --device cpu --batches 4096 --threads 1 8 14 --seconds 4
  switches
  ;;
versus)
  # This tree's learner against another's on one machine, alternating (ratios side by side).
  other=${3:?the other checkout: a folder holding the robogym_ray/ of another commit}
  for round in 1 2; do
    for tree in "$other" "$root"; do
      PYTHONPATH=$tree:$PYTHONPATH part 60 "eager, $tree, round $round" --device "$device" \
        "${all[@]}"
    done
  done
  switches
  ;;
profile)
  # Where a step's time goes (wall, kernel and host time per step), eager and compiled.
  part 50 "eager, profiled" --device "$device" --batches 1024 --seconds "$seconds" --profile 50
  part 150 "compiled, profiled" --device "$device" "${all[@]}" --warmup 30 \
    --compile reduce-overhead --profile 50
  ;;
train)
  cpus=$(nproc)
  for workers in 2 4 8 14; do
    "$py" "$root/benchmarks/scaling.py" train --task navigation --workers "$workers" --envs 4 \
      --batch $((128 * workers)) --samples-per-insert 32 --wall-s 90 --repeats 1 \
      --num-cpus "$cpus" --learner-cpus 1 --d4pg '{"compile": "reduce-overhead"}' \
      | tee -a "$out/train.jsonl"
  done
  "$py" "$root/benchmarks/scaling.py" train --task navigation --workers 8 --envs 4 \
    --batch 1024 --samples-per-insert 32 --wall-s 90 --repeats 1 --num-cpus "$cpus" \
    --learner-cpus 4 --learner-gpus 0 --d4pg '{"device": "cpu"}' | tee -a "$out/train.jsonl"
  ;;
*) echo "unknown part $part: learner, train or wheels" >&2; exit 2 ;;
esac
