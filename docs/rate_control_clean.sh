#!/usr/bin/env bash
# Whether rate control's files decode clean: for each mesh given, `ellip encode MESH
# --max-bytes N` and `--tolerance T` (one thread), then `ellip decode` of the file at its
# own density as a reader would; one table row per run (bytes, regions, ellip's RMS as a
# fraction of the diagonal, what the decoded mesh is, encode seconds) and a closing count.
#
#   bash docs/rate_control_clean.sh ../shared/meshes/{hand,teddy,bunny,horse,duck,penguin,spot,igea_small}.obj
#
# Targets: BUDGETS (default "600 1500") and TOLERANCES (default "0.005"). Needs cargo and
# python3 (to read the JSON reports).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
[[ $# -gt 0 ]] || { echo "usage: bash docs/rate_control_clean.sh MESH..." >&2; exit 2; }
budgets=${BUDGETS:-600 1500}
tolerances=${TOLERANCES:-0.005}

cargo build --release --quiet
ellip="$PWD/target/release/ellip"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cat > "$work/row.py" <<'PY'
import json, sys
e, d = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
faults = []
if d["flipped_triangles"]: faults.append(f"{d['flipped_triangles']} flipped")
if d["degenerate_triangles"]: faults.append(f"{d['degenerate_triangles']} degenerate")
if not d["manifold"]: faults.append("not manifold")
if d["omitted_regions"]: faults.append(f"{len(d['omitted_regions'])} regions left out")
decoded = ", ".join(faults) or "clean"
# A source that is not manifold decodes to a mesh that is not either: the encoder's check
# (decode_check) counts that as clean, and so does this table.
if faults == ["not manifold"] and e["decode_check"] == "clean":
    decoded = "clean (the source is not manifold)"
print(e["bytes"], e["regions"], f"{100 * e['error']['rms_fraction']:.3f}", decoded)
PY

clean=0
total=0
echo "| mesh | target | bytes | regions | RMS % | decoded | encode s |"
echo "|---|---|---:|---:|---:|---|---:|"
run() { # name label option value
  local out="$work/$1.$3$4"
  local start seconds
  start=$(date +%s.%N)
  if ! "$ellip" encode "$mesh" "--$3" "$4" --threads 1 -o "$out.ellip" --json --quiet \
    > "$out.json" 2> "$out.err"; then
    echo "| $1 | $2 | | | | fails: $(tail -n 1 "$out.err") | |"
    return
  fi
  seconds=$(echo "$(date +%s.%N) - $start" | bc)
  "$ellip" decode "$out.ellip" -o "$out.glb" --json --quiet > "$out.decoded.json" 2> /dev/null || true
  total=$((total + 1))
  read -r bytes regions rms decoded < <(python3 "$work/row.py" "$out.json" "$out.decoded.json")
  [[ $decoded == clean* ]] && clean=$((clean + 1))
  printf '| %s | %s | %s | %s | %s | %s | %.1f |\n' "$1" "$2" "$bytes" "$regions" "$rms" \
    "$decoded" "$seconds"
}
for mesh in "$@"; do
  name=$(basename "${mesh%.*}")
  for n in $budgets; do run "$name" "≤ $n bytes" max-bytes "$n"; done
  for t in $tolerances; do run "$name" "RMS ≤ $t" tolerance "$t"; done
done
echo
echo "$clean of $total files decode clean"
