#!/usr/bin/env bash
# Longer training than 2 CPU cores allow, on an NVIDIA GPU machine without a package registry
# (issue 29: "Diffusion at this budget is far behind ... longer training is GPU work"). Builds the
# train split of studies/paper_table/recipes/$RECIPE.yaml there (the experts need no mplib), then trains the camera
# learners' Diffusion Policy for $SKILL (head and wrist depth, base-frame proprioception, the
# target kind, end-effector actions, random shift 4 px: studies/learners/sanity_learners.py CAMERAS) in
# each variant of $VARIANTS at once on the one GPU, until the deadline. Brings back what a run
# folder needs to load as a policy (7 files, each under 16 MiB): per variant the weights halfway
# through and at the end (optimiser state left out), and a tarball of its config, policy files,
# losses.csv and best.pt (the lowest validation loss, a poor guide for diffusion); the closed-loop
# choice between them is made on the validation split where they come back (docs/learners.md).
# Needs the git-ignored .gpu_bundle/site312.tar.xz and .gl/ (scripts/gpu_env.sh). From the
# checkout's root:
#   OUT=/some/dir bash scripts/gpu_long_training.sh
# Options (environment): RECIPE, SKILL, WORKERS (build processes, default 15), BUILD_S (build limit,
# default 330 s), DEADLINE_S (training stops this long after the start, default 560 s), DEVICE,
# LIMIT (train episodes, for a quick check), VARIANTS ("name:options;name:options"), GPU_ENV=0
# (run with this machine's own Python instead of the bundle).
set -u
OUT=${OUT:-$PWD/gpu_out}
RECIPE=${RECIPE:-cameras_pick_place}
SKILL=${SKILL:-Pick}
WORKERS=${WORKERS:-15}
BUILD_S=${BUILD_S:-330}
DEADLINE_S=${DEADLINE_S:-560}
DEVICE=${DEVICE:-cuda}
LIMIT=${LIMIT:-}
# Two learning rates: the learners' default (1e-3) and Diffusion Policy's own (1e-4); batch 256
# (Diffusion Policy's size for its image tasks) keeps the GPU busy where 64 is launch-bound.
VARIANTS=${VARIANTS:-"diffusion_lr1e-3:--lr 1e-3;diffusion_lr1e-4:--lr 1e-4"}
WORK=${WORK:-/tmp/long_training}
mkdir -p "$OUT" "$WORK"
exec > >(tee -a "$OUT/gpu_long.log") 2>&1
START=$(date +%s)
since() { echo $(( $(date +%s) - START )); }

if [ "${GPU_ENV:-1}" = 1 ]; then source scripts/gpu_env.sh  # the bundle, the Vulkan loader and ICD, PYTHONPATH, $PY
else PY=${PY:-python}; fi  # GPU_ENV=0: this machine's own Python (a quick check of the script)
export OMP_NUM_THREADS=1 MKL_NUM_THREADS=1
date -u; nproc; nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv 2>&1 | head -3
$PY -c "import sys, numpy, torch, sapien; print('python', sys.version.split()[0], 'numpy', numpy.__version__, 'torch', torch.__version__, 'cuda', torch.cuda.is_available(), 'sapien', sapien.__version__)"
$PY -c "import sapien; print('render devices:', sapien.render.get_device_summary())" || { echo "NO RENDERING DEVICE: the build cannot render"; exit 1; }
echo "setup: $(since) s"

# --- the data ---------------------------------------------------------------------------------
DATA=$WORK/data/$RECIPE
echo "=== build $RECIPE (limit $BUILD_S s) $(date -u +%T)"
timeout -k 10 "$BUILD_S" $PY -m echo_data.cli build "studies/paper_table/recipes/$RECIPE.yaml" --split train --workers "$WORKERS" \
    --out "$DATA" --no-progress ${LIMIT:+--limit $LIMIT} > "$WORK/build.txt" 2>&1
echo "=== build rc=$? after $(since) s"; tail -n 5 "$WORK/build.txt"
$PY - "$DATA/manifest.json" <<'EOF' || { echo "NO COMPLETE BUILD: nothing to train"; exit 1; }
import json, sys
m = json.load(open(sys.argv[1]))
print("build:", json.dumps({k: m.get(k) for k in ("complete", "counts", "skills")}))
sys.exit(0 if m.get("complete") else 1)
EOF

# --- the learners, side by side on the one GPU, until the deadline ---------------------------------
COMMON="--skill $SKILL --inputs depth,wrist_depth,state,kind --action-column action.ee --shift 4 --select-every 0 --device $DEVICE --batch-size 256 --epochs 1000 --threads 4 --seed 0 --no-progress"
LEFT=$(( DEADLINE_S - $(since) ))
echo "=== training for $LEFT s $(date -u +%T)"
NAMES=(); PIDS=()
IFS=';' read -ra VS <<< "$VARIANTS"
for v in "${VS[@]}"; do
  name=${v%%:*}; opts=${v#*:}
  NAMES+=("$name")
  echo "train diffusion DATA $COMMON $opts --out RUNS/$name"
  timeout -k 10 "$LEFT" $PY -m echo_data.cli train diffusion "$DATA" $COMMON $opts --out "$WORK/runs/$name" > "$WORK/$name.txt" 2>&1 &
  PIDS+=($!)
done
weights() {  # weights CHECKPOINT DEST: the model of a training checkpoint without its optimiser state
  $PY - "$1" "$2" <<'EOF'
import sys, torch
c = torch.load(sys.argv[1], map_location="cpu", weights_only=False)
torch.save({"model": c["model"], "step": c["state"]["step"], "epoch": c["state"]["epoch"]}, sys.argv[2])
print(sys.argv[2].rsplit("/", 1)[-1], "step", c["state"]["step"], "epoch", c["state"]["epoch"])
EOF
}
sleep $(( LEFT / 2 ))  # halfway: a second candidate per variant (checkpoint.pt is replaced whole, every 30 s)
for name in "${NAMES[@]}"; do weights "$WORK/runs/$name/checkpoint.pt" "$OUT/${name}_mid.pt"; done
wait "${PIDS[@]}"  # (a bare wait would also wait for the tee above)
echo "=== training ended after $(since) s"

# --- what comes back: per run the last weights and a tarball of the small files and best.pt (8 files at most) ---
for name in "${NAMES[@]}"; do
  R=$WORK/runs/$name
  echo "--- $name"; tail -n 3 "$WORK/$name.txt"; tail -n 3 "$R/losses.csv" 2>/dev/null
  cp "$WORK/$name.txt" "$R/train_output.txt" 2>/dev/null
  weights "$R/checkpoint.pt" "$OUT/${name}_last.pt"
  (cd "$R" && tar -czf "$OUT/${name}_meta.tar.gz" $(ls | grep -v -e '^checkpoint\.pt$' -e '^select$'))  # best.pt: lowest validation loss
done
ls -la "$OUT"; echo "total: $(since) s"
