#!/usr/bin/env bash
# The env and render benchmarks on an NVIDIA GPU machine without a package registry (Python 3.12
# image with numpy 2, scipy, pyarrow, torch; see docs/vector_envs.md "On a GPU machine").
# Needs the bundle of what that image lacks, made where pip reaches the registry and carried in the
# git-ignored folder .gpu_bundle/ of the checkout:
#   EXTRA="threadpoolctl==3.8.0" bash make_bundle.sh .gpu_bundle      # writes .gpu_bundle/site312.tar.xz
# Then, from the checkout's root on the GPU machine:
#   OUT=/some/dir bash scripts/gpu_bench.sh        # outputs under $OUT (default ./gpu_out); about 5 minutes
#   TRAIN_DATA=DATASET OUT=/some/dir bash scripts/gpu_bench.sh   # training a skill on the GPU first
# Every part runs under a share of one overall deadline (BUDGET_S, default 330 s) and the script
# goes on past a part that fails or runs out of time; each part's output is in its own file.
set -u
set -x
OUT=${OUT:-$PWD/gpu_out}
mkdir -p "$OUT"
exec > >(tee -a "$OUT/gpu_bench.log") 2>&1
START=$(date +%s)
BUDGET_S=${BUDGET_S:-330}
RECIPE=recipes/multi_event.yaml

part() {  # part NAME SECONDS CMD...: run CMD with at most SECONDS (less if the budget is nearly spent)
  local name=$1 secs=$2; shift 2
  local left=$(( BUDGET_S - ($(date +%s) - START) ))
  if (( left < 15 )); then echo "SKIPPED $name: budget spent" | tee "$OUT/$name.txt"; return 0; fi
  (( secs > left )) && secs=$left
  echo "=== $name (limit ${secs} s) $(date -u +%T)"
  timeout -k 5 "$secs" "$@" > "$OUT/$name.txt" 2>&1
  local rc=$?
  echo "=== $name rc=$rc after $(( $(date +%s) - START )) s"
  tail -n 25 "$OUT/$name.txt"
}

# --- the bundle and the environment -----------------------------------------------------------
source scripts/gpu_env.sh  # the bundle, the Vulkan loader and ICD, PYTHONPATH, $PY

# --- versions and the machine ---------------------------------------------------------------------
{
  date -u; uname -a; nproc; free -g | head -2
  nvidia-smi --query-gpu=name,driver_version,memory.total,utilization.gpu --format=csv 2>&1 | head -3
  git log --oneline -1 2>/dev/null || true
  $PY - <<'EOF'
import importlib, sys
print("python", sys.version.split()[0])
for m in ("numpy", "scipy", "sapien", "gymnasium", "pydantic", "pyarrow", "threadpoolctl", "torch"):
    try:
        print(m, getattr(importlib.import_module(m), "__version__", "?"))
    except Exception as e:
        print(m, "MISSING", type(e).__name__, e)
import sapien
print("render devices:", sapien.render.get_device_summary())
EOF
} > "$OUT/versions.txt" 2>&1
cat "$OUT/versions.txt"

# --- training a skill on the GPU (issue 29), when a dataset travels in TRAIN_DATA ------------------
# TRAIN_DATA: a `studies/paper_table/recipes/cameras_pick_place.yaml` build (or its Pick rows alone: a dataset must fit the
# 64 MiB the working tree may carry). The camera learners' Pick: ACT on head and wrist depth,
# proprioception and the target kind, end-effector actions, random shift 4 px.
TRAIN_DATA=${TRAIN_DATA:-}
CAM="--skill Pick --inputs depth,wrist_depth,state,kind --action-column action.ee --shift 4"
if [ -n "$TRAIN_DATA" ] && [ -f "$TRAIN_DATA/manifest.json" ]; then
  # samples/s on the GPU and on one CPU thread of the same machine (same data, same run), then the
  # camera learners' whole Pick optimisation (7,500 steps: 20 epochs of the 150-episode build) on the
  # GPU, or as many steps as its measured rate fits in FULL_S seconds
  part train_speed ${TRAIN_S:-260} $PY benchmarks/train_speed.py "$TRAIN_DATA" --algo act --steps 200 $CAM --devices cuda,cpu \
      --full-steps 7500 --full-budget ${FULL_S:-150}
fi

# --- the benchmarks, most wanted first -------------------------------------------------------------
# 1. one env (listening thread + prefetch, the default) against the floor, and 2 async processes
part bench_env 90 $PY benchmarks/bench_env.py $RECIPE --steps 150 --episodes 2
# 2. N async envs with every observation (one process measured in the same run; stragglers; threads)
part bench_vec 150 $PY benchmarks/bench_vec.py $RECIPE --n 1 --n 4 --n 8 --n 14 --steps 40
# 3. the same env step with the audio in the caller's thread, no prefetch (the code before this work)
part bench_env_inline 60 env ECHO_DATA_LISTENER=0 $PY benchmarks/bench_env.py $RECIPE --steps 150 --episodes 2
# 4. cameras: textured / flat looks at 128, 224, 256 pixels
part bench_render 45 $PY benchmarks/bench_render.py $RECIPE --steps 60
# 5. 14 async envs without prefetch (does the idle-time work help or hurt when every core is busy?)
part bench_vec_noprefetch 50 env ECHO_DATA_PREFETCH=0 $PY benchmarks/bench_vec.py $RECIPE --n 14 --steps 40

echo "done in $(( $(date +%s) - START )) s; outputs:"; ls -la "$OUT"
exit 0
