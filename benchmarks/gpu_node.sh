#!/usr/bin/env bash
# Issue 42's GPU figures on a 16-core node with one GPU, in two parts of under 10 minutes each:
#   bash benchmarks/gpu_node.sh learner OUT   the learner alone on CUDA, batch 256 to 16,384,
#                                             eager and compiled (CUDA graphs), then bf16;
#   bash benchmarks/gpu_node.sh train OUT     90-s navigation trainings with 2, 4, 8 and 14
#                                             workers and the GPU learner, then 8 workers with
#                                             the CPU learner (one thread per learner CPU).
# Each writes JSON lines to OUT/<part>.jsonl; docs/scaling.md says how they are read.
set -euo pipefail
part=${1:?learner or train}
out=${2:?output folder}
mkdir -p "$out"
export PYTHONUNBUFFERED=1 RAY_AUTH_MODE=disabled
nvidia-smi --query-gpu=name,memory.total --format=csv,noheader | tee "$out/device.txt"
nproc >> "$out/device.txt"
case "$part" in
learner)
  python benchmarks/learner_capacity.py alone --device cuda --batches 256 1024 4096 16384 \
    --seconds 5 | tee "$out/learner.jsonl"
  python benchmarks/learner_capacity.py alone --device cuda --batches 256 1024 4096 16384 \
    --seconds 5 --warmup 30 --compile reduce-overhead | tee -a "$out/learner.jsonl"
  python benchmarks/learner_capacity.py alone --device cuda --batches 4096 16384 \
    --seconds 5 --warmup 30 --compile reduce-overhead --bf16 --sgd-steps 8 \
    | tee -a "$out/learner.jsonl"
  ;;
train)
  cpus=$(nproc)
  for workers in 2 4 8 14; do
    python benchmarks/scaling.py train --task navigation --workers "$workers" --envs 4 \
      --batch $((128 * workers)) --samples-per-insert 32 --wall-s 90 --repeats 1 \
      --num-cpus "$cpus" --learner-cpus 1 --d4pg '{"compile": "reduce-overhead"}' \
      | tee -a "$out/train.jsonl"
  done
  python benchmarks/scaling.py train --task navigation --workers 8 --envs 4 --batch 1024 \
    --samples-per-insert 32 --wall-s 90 --repeats 1 --num-cpus "$cpus" --learner-cpus 4 \
    --learner-gpus 0 --d4pg '{"device": "cpu"}' | tee -a "$out/train.jsonl"
  ;;
*) echo "unknown part $part: learner or train" >&2; exit 2 ;;
esac
