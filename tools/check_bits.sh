#!/usr/bin/env bash
# Behaviour-preserving refactors prove it: run `fricsens validate` on a worktree and compare every
# value it writes with a baseline report directory (validation/ of the commit before the
# refactor, or a copy of it): every data/*-sensitivities.csv byte for byte, every
# data/*-errors.csv but its cost_ratio column (a timing).
#
# usage: tools/check_bits.sh BASELINE_DIR [WORKTREE]
#   e.g. git worktree add /tmp/base <commit> && tools/check_bits.sh /tmp/base/validation .
set -euo pipefail
base=$(cd "${1:?baseline report directory}" && pwd)
cd "${2:-.}"
cargo build --release --bin fricsens 2>&1 | tail -1
out=$(mktemp -d)
./target/release/fricsens validate --out "$out" > "$out/log" 2>&1 || { echo "validate failed"; tail "$out/log"; exit 1; }
ok=1
for f in "$base"/data/*-sensitivities.csv; do
  b=$(basename "$f")
  cmp -s "$f" "$out/data/$b" || { echo "DIFFERS: $b"; ok=0; }
done
for f in "$base"/data/*-errors.csv; do
  b=$(basename "$f")
  diff <(cut -d, -f1-5,7- "$f") <(cut -d, -f1-5,7- "$out/data/$b") > /dev/null || { echo "DIFFERS: $b (beyond cost_ratio)"; ok=0; }
done
echo "oracle checks passing: $(grep -c '"pass": *true' "$out/data/validation.json" || true)"
[ $ok = 1 ] && echo "ALL VALUE CSVs BIT-IDENTICAL ($out)" || { echo "see $out"; exit 1; }
