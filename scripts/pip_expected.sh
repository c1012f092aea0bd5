#!/usr/bin/env bash
# Sourced by the setup scripts: `pip_expected PYTHON WHY -- PIP-INSTALL-ARGS...` runs
# `PYTHON -m pip install -q` and, where pip lists dependency conflicts (a package installed
# without its declared dependencies on purpose: robomimic beside the CPU torch, lerobot 0.4.4
# around its torch<2.11 pin), prints one line that names the packages and says why the
# conflict is expected instead of pip's ERROR block. Any other output is passed on; a failed
# install prints everything and fails.
pip_expected() {
  local py=$1 why=$2 log rc=0
  shift 3
  log=$(mktemp)
  "$py" -m pip install -q --disable-pip-version-check "$@" >"$log" 2>&1 || rc=$?
  if [ "$rc" != 0 ]; then cat "$log" >&2; rm -f "$log"; return "$rc"; fi
  local pattern="^(ERROR: pip's dependency resolver does not currently take into account|[A-Za-z0-9_.-]+ [^ ]+ requires )"
  grep -v -E "$pattern" "$log" >&2 || true
  if grep -q "^ERROR: pip's dependency resolver" "$log"; then
    local pkgs
    pkgs=$(grep -E "^[A-Za-z0-9_.-]+ [^ ]+ requires " "$log" | awk '{print $1" "$2}' | sort -u | paste -sd, -)
    echo "setup: pip lists $(grep -c -E "^[A-Za-z0-9_.-]+ [^ ]+ requires " "$log") unmet declared requirements of $pkgs: expected ($why)"
  fi
  rm -f "$log"
}
