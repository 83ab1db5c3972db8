#!/usr/bin/env bash
# Behaviour-preserving changes to the F-bar kernel prove it: no built-in scene has an F-bar
# body, so this runs DDM and the adjoint (`--at all`) with two binaries on physics-fuzzer
# scenes that do (`fricsens fuzz --show SEED`: J2, SVK and Neo-Hookean F-bar hex8, large and
# small kinematics, plane strain and 3D), for the F-bar body's E, nu, length.x (a shape
# parameter: the reference nodes then carry derivatives) and sigma_y where it has one, and
# compares every sensitivity.csv byte for byte. A von Mises stress response of the F-bar
# body's first element is added to each scene. Needs Python 3.11 (tomllib).
#
# usage: tools/check_fbar_bits.sh BASE_BINARY NEW_BINARY [SEED ...]   (paths to the binaries)
#   the default seeds: 63 62 95 100 98 80 32 127 135 147
set -euo pipefail
base=$(realpath "${1:?base binary}")
new=$(realpath "${2:?new binary}")
shift 2
seeds=("$@")
[ ${#seeds[@]} -eq 0 ] && seeds=(63 62 95 100 98 80 32 127 135 147)
out=$(mktemp -d)
ok=1
for s in "${seeds[@]}"; do
  scene="$out/seed-$s.toml"
  "$new" fuzz --show "$s" > "$scene"
  # the F-bar body's parameters, and a stress response on its first element appended to
  # the scene (the Cauchy stress's volume reads det F: the kernel's want_cauchy path)
  params_line=$(python3 - "$scene" <<'PY'
import sys, tomllib
path = sys.argv[1]
scene = tomllib.load(open(path, "rb"))
body = next((b for b in scene["bodies"] if b.get("formulation") == "f-bar"), None)
if body is None:
    sys.exit(f"{path}: no F-bar body")
with open(path, "a") as f:
    f.write(f'\n[[responses]]\nkind = "stress"\nname = "fbar-stress"\nbody = "{body["name"]}"\n'
            'element = 0\nmeasure = "von-mises"\n')
names = ["E", "nu", "length.x"] + (["sigma_y"] if "sigma_y" in body["material"] else [])
print(" ".join(f"--param {body['name']}.{n}" for n in names))
PY
)
  read -r -a params <<< "$params_line"
  for method in ddm adjoint; do
    extra=()
    [ $method = adjoint ] && extra=(--at all)
    for which in base new; do
      bin=$base
      [ $which = new ] && bin=$new
      dir="$out/$which/$s-$method"
      mkdir -p "$out/$which"
      "$bin" sensitivity "$scene" --method $method "${extra[@]}" "${params[@]}" --out "$dir" \
        > "$dir.log" 2>&1 || { echo "seed $s $method: $which failed (see $dir.log)"; ok=0; }
    done
    a="$out/base/$s-$method/sensitivity.csv"
    b="$out/new/$s-$method/sensitivity.csv"
    if [ -f "$a" ] && [ -f "$b" ] && cmp -s "$a" "$b"; then
      echo "seed $s $method (${params[*]}): identical"
    else
      echo "seed $s $method: DIFFERS"
      ok=0
    fi
  done
done
[ $ok = 1 ] && echo "ALL F-BAR SENSITIVITY CSVs BIT-IDENTICAL ($out)" || { echo "see $out"; exit 1; }
