#!/usr/bin/env bash
# Rate control checked by a metric that is not ellip's (issue 7): for each mesh given,
# `ellip encode MESH --tolerance T` must give a file whose decoded mesh is within T RMS of
# the mesh as MeshLab's Metro measures it (pymeshlab's get_hausdorff_distance: 200 000
# points sampled by area on each mesh, exact closest points on the other, both ways, as a
# fraction of the mesh's bounding-box diagonal), and `ellip encode MESH --max-bytes N` a
# file of at most N bytes. Prints one table row per run and a closing count; exits 1 when a
# target is missed.
#
#   bash docs/cgal_meshes.sh && bash docs/rate_control_check.sh target/cgal-meshes/*.off
#
# Targets: TOLERANCES (default "0.01 0.005") and BUDGETS (default "800 1500 3000").
# Metro samples other points than ellip does: an RMS is counted as met up to SLACK (default
# 0.02, 2 %) above T, more than the two samplings disagree (measured: at most 0.9 %).
# Needs python3 with venv and pip (pymeshlab goes into target/metro-venv) and cargo.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
[[ $# -gt 0 ]] || { echo "usage: bash docs/rate_control_check.sh MESH..." >&2; exit 2; }
tolerances=${TOLERANCES:-0.01 0.005}
budgets=${BUDGETS:-800 1500 3000}
slack=${SLACK:-0.02}

cargo build --release --quiet
ellip="$PWD/target/release/ellip"
venv="$PWD/target/metro-venv"
if [[ ! -x $venv/bin/python ]] || ! "$venv/bin/python" -c 'import pymeshlab' 2>/dev/null; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install --quiet pymeshlab
fi
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cat > "$work/metro.py" <<'PY'
import sys, pymeshlab
ms = pymeshlab.MeshSet()
ms.load_new_mesh(sys.argv[1])
ms.load_new_mesh(sys.argv[2])
diag = ms.mesh(0).bounding_box().diagonal()
rms, worst = 0.0, 0.0
for a, b in ((0, 1), (1, 0)):
    r = ms.get_hausdorff_distance(sampledmesh=a, targetmesh=b, samplevert=False,
                                  sampleface=True, samplenum=200000,
                                  maxdist=pymeshlab.PureValue(diag))
    rms, worst = max(rms, r["RMS"] / diag), max(worst, r["max"] / diag)
print(f"{rms:.6f} {worst:.6f}")
PY
cat > "$work/report.py" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
print(f"{r['requested_regions']}→{r['regions']}", r["error"]["rms_fraction"])
PY

passed=0
failed=0
echo "| mesh | target | K → regions | bytes | ellip RMS | Metro RMS | Metro Hausdorff | seconds | met |"
echo "|---|---|---:|---:|---:|---:|---:|---:|---|"
for mesh in "$@"; do
  name=$(basename "${mesh%.*}")
  for t in $tolerances; do
    out="$work/$name.tol$t"
    start=$(date +%s.%N)
    if "$ellip" encode "$mesh" --tolerance "$t" -o "$out.ellip" --json --quiet > "$out.json" 2> "$out.err"; then
      seconds=$(echo "$(date +%s.%N) - $start" | bc)
      if ! "$ellip" decode "$out.ellip" -o "$out.obj" --quiet; then
        failed=$((failed + 1))
        echo "| $name | RMS ≤ $t | | | | | | | NO: the file does not decode |"
        continue
      fi
      read -r metro hausdorff < <("$venv/bin/python" "$work/metro.py" "$mesh" "$out.obj")
      read -r k measured < <("$venv/bin/python" "$work/report.py" "$out.json")
      met=$(echo "$metro <= $t * (1 + $slack)" | bc -l)
      [[ $met == 1 ]] && passed=$((passed + 1)) || failed=$((failed + 1))
      printf '| %s | RMS ≤ %s | %s | %s | %.5f | %.5f | %.4f | %.1f | %s |\n' "$name" "$t" "$k" \
        "$(stat -c %s "$out.ellip")" "$measured" "$metro" "$hausdorff" "$seconds" \
        "$([[ $met == 1 ]] && echo yes || echo NO)"
    else
      failed=$((failed + 1))
      echo "| $name | RMS ≤ $t | | | | | | | NO: $(tail -n 1 "$out.err") |"
    fi
  done
  for n in $budgets; do
    out="$work/$name.max$n"
    start=$(date +%s.%N)
    if "$ellip" encode "$mesh" --max-bytes "$n" -o "$out.ellip" --json --quiet > "$out.json" 2> "$out.err"; then
      seconds=$(echo "$(date +%s.%N) - $start" | bc)
      bytes=$(stat -c %s "$out.ellip")
      read -r k measured < <("$venv/bin/python" "$work/report.py" "$out.json")
      [[ $bytes -le $n ]] && passed=$((passed + 1)) || failed=$((failed + 1))
      printf '| %s | ≤ %s bytes | %s | %s | %.5f | | | %.1f | %s |\n' "$name" "$n" "$k" "$bytes" \
        "$measured" "$seconds" "$([[ $bytes -le $n ]] && echo yes || echo NO)"
    else
      # Nothing fits: an error, never an overrun; counted apart.
      echo "| $name | ≤ $n bytes | | | | | | | none fits: $(tail -n 1 "$out.err") |"
    fi
  done
done
echo
echo "$passed passed, $failed failed"
[[ $failed -eq 0 ]]
