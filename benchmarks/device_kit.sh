#!/usr/bin/env bash
# A kit of wheels for a GPU node that has torch and no network, so that a training runs there.
#
#   bash benchmarks/device_kit.sh               here, with pip's registry and a python3.12 (with
#                                               pyenv: PYENV_VERSION=3.12.1): builds
#                                               .device-kit/kit.tar.xz (git-ignored) and prints its
#                                               size beside the working tree's; the zip and
#                                               metadata work is benchmarks/device_kit.py
#   bash benchmarks/device_kit.sh install DIR   on the node, from the checkout's root: installs the
#                                               kit into DIR with pip --no-index (no network), then
#                                               imports robogym_ray, ray, pybullet and gymnasium
#
# then `export PYTHONPATH=DIR:$PWD` (the checkout is not installed; DIR goes first, so the kit's
# grpcio and protobuf win over the node's). The node (as the H100 nodes of 2026-11-26 and
# 2026-11-27 were, docs/benchmarks.md 15e and 16): CPython 3.12 on manylinux x86-64 with torch,
# numpy, grpcio, protobuf, tensorboard, pyarrow, scipy, ... (NODE_HAS below), and no ray,
# pybullet, gymnasium nor jsonschema.
#
# Why a kit and not wheels as they come: what goes to the node with one command is the working
# tree and the paths it names, 64 MiB in all; ray's wheel alone is 79 MB and pybullet has no wheel
# for Python 3.12. So:
#   - ray's wheel repacked without its Java jar (32 MB zipped) and the dashboard's source maps, its
#     shared objects and its gcs_server and raylet stripped (their symbols are most of their size);
#   - pybullet built here from its sdist with python3.12, without pybullet_data's files (the
#     project loads none of them), stripped; built once (minutes), then taken from the cache.
#     Built on Debian 12, its extension needs glibc >= 2.34 and libstdc++ GLIBCXX_3.4.29 (gcc 11)
#     on the node; `install` imports it, so a node older than that fails there, in seconds;
#   - grpcio and protobuf at the lock's versions: the committed generated code needs protobuf >=
#     7.35 and grpcio >= 1.85.1, and the node's versions are not known;
#   - every wheel stored uncompressed and the lot packed as one tar.xz: xz over the whole kit
#     compresses Python sources and binaries far better than zip member by member.
# Versions come from requirements/lock.txt. The build checks the project's dependencies and every
# Requires-Dist of the kit's wheels (with the extras the project names, less LEFT_OUT) against the
# kit and NODE_HAS, and fails on a gap.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
kit=$root/.device-kit
mode=${1:-build}

# What the node has (PEP 503 names, versions unknown); KIT_NODE_HAS overrides for another node.
NODE_HAS=${KIT_NODE_HAS:-"absl-py aiohttp aiosignal attrs certifi charset-normalizer click
cloudpickle filelock frozenlist fsspec grpcio idna jinja2 markupsafe matplotlib msgpack multidict
numpy packaging pandas pillow protobuf psutil pyarrow pyyaml requests scipy setuptools six
tensorboard tqdm typing-extensions urllib3 yarl zipp propcache aiohappyeyeballs pytest torch"}
# What the node lacks, at the lock's versions (ray and pybullet are handled apart, below).
# tensorboardx and pydantic: ray[tune] (robogym-ray sweep).
CARRIED="gymnasium farama-notifications jsonschema referencing rpds-py jsonschema-specifications
grpcio protobuf tensorboardx pydantic pydantic-core annotated-types typing-inspection"
# The extras the project names that the kit leaves out: ray[default] is the dashboard and the
# metrics agent, and the embedded Ray starts without the dashboard (distributed/local_ray.py).
LEFT_OUT="ray[default]"
# One device call's carry limit: the working tree and the carried paths together.
LIMIT=67108864
# Changes to how ray and pybullet are repacked or built change this, so the cache is not reused.
RECIPE=r1

if [ "$mode" = install ]; then
  target=${2:?target folder, e.g. /tmp/site}
  py=$(command -v "${PYTHON:-python3}") # absolute: the import check below runs from /
  [ -f "$kit/kit.tar.xz" ] || {
    echo "no $kit/kit.tar.xz: build it where pip works and carry .device-kit" >&2
    exit 2
  }
  tmp=$(mktemp -d)
  trap 'rm -rf "$tmp"' EXIT
  # Python's own tarfile: the node needs no xz program.
  "$py" -c 'import sys, tarfile; tarfile.open(sys.argv[1]).extractall(sys.argv[2], filter="data")' \
    "$kit/kit.tar.xz" "$tmp"
  "$py" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
    --target "$target" "$tmp"/*.whl
  (cd / && PYTHONPATH=$target:$root "$py" -c '
import google.protobuf, grpc, gymnasium, pybullet, ray, robogym_ray
print("ray", ray.__version__, "gymnasium", gymnasium.__version__, "grpcio", grpc.__version__,
      "protobuf", google.protobuf.__version__)')
  echo "export PYTHONPATH=$target:$root"
  exit 0
fi
[ "$mode" = build ] || {
  echo "usage: $0 [build] | install DIR" >&2
  exit 2
}

py312=${KIT_PYTHON:-python3.12}
cache=${XDG_CACHE_HOME:-$HOME/.cache}/robogym-ray-kit
venv=$cache/venv-py312
if [ ! -x "$venv/bin/python" ]; then
  # numpy 2.0's headers: pybullet built with numpy support (as its own wheels are) runs on any
  # numpy >= 2.0 (and on 1.x; numpy 2's default C-API target is older).
  "$py312" -m venv "$venv"
  "$venv/bin/python" -m pip install -q setuptools==84.2.1 wheel numpy==2.0.2 packaging==26.3
fi
bpy=$venv/bin/python
"$bpy" -c 'import sys; assert sys.version_info[:2] == (3, 12), sys.version' || {
  echo "$py312 is not Python 3.12: set KIT_PYTHON" >&2
  exit 2
}
# The zip and metadata work (benchmarks/device_kit.py), in the build venv's Python: it has
# `packaging`.
helper() { "$bpy" "$root/benchmarks/device_kit.py" "$@"; }

# NAME==VERSION -> its cp312 manylinux x86-64 wheel, downloaded once into the cache.
fetch() {
  local dir=$cache/download/$1
  if ! compgen -G "$dir/*.whl" >/dev/null; then
    "$bpy" -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 \
      --implementation cp --platform manylinux2014_x86_64 --platform manylinux_2_17_x86_64 \
      --platform manylinux_2_28_x86_64 -d "$dir" "$1" >&2
  fi
  echo "$dir"/*.whl
}

ray_pin=$(helper locked "$root/requirements/lock.txt" ray)
ray_dir=$cache/${ray_pin/==/-}-$RECIPE
if ! compgen -G "$ray_dir/*.whl" >/dev/null; then
  echo "repacking $ray_pin"
  mkdir -p "$ray_dir"
  helper repack "$(fetch "$ray_pin")" "$ray_dir" 'ray/jars/ray_dist.jar' 'ray/dashboard/*.js.map'
fi

pb_pin=$(helper locked "$root/requirements/lock.txt" pybullet)
pb_dir=$cache/${pb_pin/==/-}-$RECIPE
if ! compgen -G "$pb_dir/*.whl" >/dev/null; then
  sdist_dir=$cache/download/$pb_pin-sdist
  if ! compgen -G "$sdist_dir/*.tar.gz" >/dev/null; then
    "$bpy" -m pip download -q --no-deps --no-binary=:all: --no-build-isolation -d "$sdist_dir" \
      "$pb_pin"
  fi
  echo "building $pb_pin from its sdist with $("$bpy" -V) (minutes)"
  work=$(mktemp -d)
  tar -xzf "$sdist_dir"/*.tar.gz -C "$work"
  src=("$work"/pybullet-*)
  # pybullet_data's files (URDFs, meshes, textures: 148 MB) go; its __init__.py stays.
  find "${src[0]}/examples/pybullet/gym/pybullet_data" -mindepth 1 \
    ! -path '*/pybullet_data/__init__.py' -delete
  "$bpy" -m pip wheel -q --no-deps --no-build-isolation -w "$work/wheel" "${src[0]}" \
    >"$work/build.log" 2>&1 || {
    tail -30 "$work/build.log" >&2
    exit 1
  }
  mkdir -p "$pb_dir"
  helper repack "$work"/wheel/*.whl "$pb_dir"
  rm -rf "$work"
fi

stage=$cache/stage
rm -rf "$stage"
mkdir -p "$stage"
cp "$ray_dir"/*.whl "$pb_dir"/*.whl "$stage"/
# shellcheck disable=SC2086 # CARRIED is a list of names
for pin in $(helper locked "$root/requirements/lock.txt" $CARRIED); do
  helper repack "$(fetch "$pin")" "$stage"
done
helper check "$stage" "$root/pyproject.toml" "$NODE_HAS" "$LEFT_OUT"

mkdir -p "$kit"
rm -f "$kit"/*
tar -C "$stage" --sort=name -cf - . | xz -9e -T0 >"$kit/kit.tar.xz.part"
mv "$kit/kit.tar.xz.part" "$kit/kit.tar.xz"

echo "kit (wheels stored uncompressed, bytes):"
(cd "$stage" && for f in *.whl; do printf '  %11d  %s\n' "$(stat -c %s "$f")" "$f"; done)
stored=$(cat "$stage"/*.whl | wc -c)
packed=$(stat -c %s "$kit/kit.tar.xz")
tree=$(helper tree "$root")
total=$((tree + packed))
printf '  %11d  all wheels\n  %11d  .device-kit/kit.tar.xz\n' "$stored" "$packed"
printf '  %11d  working tree (git ls-files -co --exclude-standard)\n' "$tree"
printf '  %11d  tree + kit, against one call'"'"'s %d (64 MiB): ' "$total" "$LIMIT"
if [ "$total" -le "$LIMIT" ]; then
  echo "fits, $((LIMIT - total)) to spare"
else
  echo "DOES NOT FIT, $((total - LIMIT)) over"
fi
cat <<EOF
Carry .device-kit with the call; on the node, from the checkout's root:
  bash benchmarks/device_kit.sh install /tmp/site && export PYTHONPATH=/tmp/site:\$PWD
EOF
