#!/usr/bin/env bash
# The privileged sanity learner per manipulation skill (studies/learners/sanity_learners.py) on an NVIDIA
# GPU machine without a package registry (Python 3.12 image with numpy 2, scipy, pyarrow, torch with
# CUDA). Needs the bundle of what that image lacks in the git-ignored .gpu_bundle/site312.tar.xz of
# the checkout (as scripts/gpu_bench.sh). From the checkout's root:
#   OUT=/some/dir bash scripts/gpu_sanity.sh      # outputs under $OUT (default ./gpu_out)
# (SANITY_COMMIT=<hash> names the commit in the JSON where the copy has no .git; WORKERS, BUDGET_S,
# SKILLS="Pick OpenDoor" and EXTRA="--epochs 20 ..." are optional; STUDY=camera_learners runs the
# camera learners instead, studies/learners/camera_learners.py: the same path with both depth cameras
# rendered, so that one needs the NVIDIA Vulkan ICD.)
# Skills in the order Pick, OpenDoor, CloseSink, Place, each with its own share of one overall
# deadline (BUDGET_S, default 480 s); a skill that fails or runs out of time is reported and the
# next goes on (datasets, run folders and evaluations already done are reused by the next skill and
# by a second run with the same WORK). Writes $OUT/$STUDY.json, $OUT/<skill>.txt (the
# driver's output), $OUT/$STUDY.log (every echo-data command's output), $OUT/versions.txt
# and prints where the time went.
# Rendering: the sanity recipes turn both cameras off and the learner reads no image, so the build
# takes no picture and evaluation makes no render system at all: Vulkan is not needed. The ICD is
# still exported (as gpu_bench.sh) because the build's World creates SAPIEN's render system (with no
# camera) and that wants some Vulkan device; without one, set it to lavapipe's or expect the build
# to fail at its first episode.
set -u
OUT=${OUT:-$PWD/gpu_out}
WORKERS=${WORKERS:-14}
BUDGET_S=${BUDGET_S:-480}
SKILLS=${SKILLS:-"Pick OpenDoor CloseSink Place"}
EXTRA=${EXTRA:-}                  # more options for the driver, e.g. "--epochs 20 --select-every 10"
STUDY=${STUDY:-sanity_learners}   # or camera_learners
case "$STUDY" in
  sanity_learners) WORK=${WORK:-$PWD/out/sanity} ;;    # datasets and run folders (large; not copied back)
  camera_learners) WORK=${WORK:-$PWD/out/cameras} ;;
  *) echo "gpu_sanity.sh: STUDY=$STUDY: expected sanity_learners or camera_learners" >&2; exit 2 ;;
esac
mkdir -p "$OUT" "$WORK"
exec > >(tee -a "$OUT/gpu_sanity.log") 2>&1
START=$(date +%s)

# --- the bundle and the environment -----------------------------------------------------------
source scripts/gpu_env.sh  # the bundle, the Vulkan loader and ICD, PYTHONPATH, $PY
export OMP_NUM_THREADS=1 MKL_NUM_THREADS=1  # one torch thread per worker process
{
  date -u; nproc; free -g | head -2
  nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv 2>&1 | head -3
  git log --oneline -1 2>/dev/null || true
  $PY -c "import sys, numpy, torch, sapien; print('python', sys.version.split()[0], 'numpy', numpy.__version__, 'torch', torch.__version__, 'cuda', torch.cuda.is_available(), 'sapien', sapien.__version__)"
} > "$OUT/versions.txt" 2>&1
cat "$OUT/versions.txt"
echo "setup: $(( $(date +%s) - START )) s"

# --- one skill at a time, each with an even share of what is left ----------------------------------
set -- $SKILLS
COUNT=$#
for SKILL in "$@"; do
  LEFT=$(( BUDGET_S - ($(date +%s) - START) ))
  if (( LEFT < 20 )); then echo "SKIPPED $SKILL: budget spent" | tee "$OUT/$SKILL.txt"; COUNT=$(( COUNT - 1 )); continue; fi
  SHARE=$(( LEFT / COUNT ))
  (( SHARE < 60 && LEFT >= 60 )) && SHARE=60  # the first skill builds the shared data: never starve it
  T0=$(date +%s)
  echo "=== $SKILL (limit ${SHARE} s) $(date -u +%T)"
  # The driver merges into the JSON it finds, so every skill's figures end up in one file.
  timeout -k 10 "$SHARE" $PY "studies/learners/$STUDY.py" --skills "$SKILL" --workers "$WORKERS" \
      --work "$WORK" --out "$OUT/$STUDY.json" $EXTRA > "$OUT/$SKILL.txt" 2>&1
  RC=$?
  echo "=== $SKILL rc=$RC in $(( $(date +%s) - T0 )) s (total $(( $(date +%s) - START )) s)"
  tail -n 12 "$OUT/$SKILL.txt"
  COUNT=$(( COUNT - 1 ))
done
cp -f "$WORK/$STUDY.log" "$OUT/" 2>/dev/null

# --- where the time went ------------------------------------------------------------------------
echo "=== where the time went (s): every echo-data command, from each skill's output"
grep -h "^  *[0-9.]* s  " "$OUT"/*.txt 2>/dev/null
$PY - "$OUT/$STUDY.json" <<'EOF' 2>/dev/null || true
import json, sys
d = json.load(open(sys.argv[1]))
for s, t in d.get("timings", {}).items():
    print(f"  {s}: {t}")
for s, f in d.get("failed", {}).items():
    print(f"  {s}: FAILED {f}")
for b in ("skills", "skills_handover"):
    print(b, {s: f"{v['successes']}/{v['n']} [{v['low']:.2f}, {v['high']:.2f}]" for s, v in d.get(b, {}).items()})
EOF
echo "done in $(( $(date +%s) - START )) s; outputs:"; ls -la "$OUT"
exit 0
