#!/usr/bin/env bash
# Behaviour-preserving changes to the adjoint prove it: run `fricsens sensitivity --method
# adjoint` with two binaries on ten built-in scenes (--at all: every response at every
# increment, the forward-dual path above 64 columns included), on element and nodal shape
# fields of the coarse leaf spring, and on the leaf spring with --tangent last, and compare
# every sensitivity.csv byte for byte.
#
# usage: tools/check_adjoint_bits.sh BASE_BINARY NEW_BINARY
#   e.g. git worktree add /tmp/base <commit> && (cd /tmp/base && cargo build --release --bin fricsens)
#        tools/check_adjoint_bits.sh /tmp/base/target/release/fricsens target/release/fricsens
set -euo pipefail
base=$(realpath "${1:?base binary}")
new=$(realpath "${2:?new binary}")
out=$(mktemp -d)
cases=()
for sc in leaf-spring indentation strip-pullout jenkins contact-patch sliding-block uniaxial-j2 \
  klarbring-2dof stacked-leaves hertz; do
  cases+=("$sc|$sc --at all")
done
cases+=("sigma-y-field|leaf-spring-coarse --at all --param upper.sigma_y[*] --param mu")
cases+=("shape-field|leaf-spring-coarse --at all --param upper.all.y[*] --param upper.E")
cases+=("last|leaf-spring --tangent last")
ok=1
for c in "${cases[@]}"; do
  name=${c%%|*}
  read -r -a args <<< "${c#*|}"
  for which in base new; do
    bin=$base; [ $which = new ] && bin=$new
    mkdir -p "$out/$which/$name"
    (cd "$out/$which/$name" && "$bin" sensitivity "${args[@]}" --method adjoint > log.txt 2>&1) \
      || { echo "$name: $which failed (see $out/$which/$name/log.txt)"; ok=0; }
  done
  a=$(find "$out/base/$name" -name sensitivity.csv)
  b=$(find "$out/new/$name" -name sensitivity.csv)
  if [ -n "$a" ] && [ -n "$b" ] && cmp -s "$a" "$b"; then echo "$name: identical"; else echo "$name: DIFFERS"; ok=0; fi
done
[ $ok = 1 ] && echo "ALL ADJOINT SENSITIVITY CSVs BIT-IDENTICAL ($out)" || { echo "see $out"; exit 1; }
