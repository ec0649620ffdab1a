#!/usr/bin/env bash
# The variable-step accuracy of the current built-in sweeps (baker version 12,
# the lattice chosen per object) pooled into one table
# (accuracy_variable_step-builtin-v12.txt; session 38, lattice and sponge added in session 43, gear, tree and text-panel in session 44; gear and spring under the tie rule in session 46).
# Usage: results/profile/trained/builtin/pooled.sh [path/to/nerflex]
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
N="$(realpath "${1:-target/release/nerflex}")"
S="$HERE/../../../bake/trained/builtin"
T="$(mktemp)"
O="$(mktemp)"
trap 'rm -f "$T" "$O"' EXIT
SWEEPS="ball-eval-budget-choose-v12 vase-eval-budget-choose-v12 box-eval-budget-choose-v12 torus-eval-budget-choose-v12 mug-eval-budget-choose-v12 spring-eval-budget-tie-v12 pawn-eval-budget-v12 lattice-eval-budget-choose-v12 sponge-eval-budget-choose-v12 gear-eval-budget-tie-v12 tree-eval-budget-choose-v12 text-panel-eval-budget-choose-v12"
first=1
for s in $SWEEPS; do
  if [ $first = 1 ]; then cat "$S/$s.csv"; first=0; else tail -n +2 "$S/$s.csv"; fi
done > "$T"
# Into a temporary file first: a failed run leaves the committed table as it was.
"$N" profile accuracy --samples "$T" --train-on variable-step > "$O"
mv "$O" "$HERE/accuracy_variable_step-builtin-v12.txt"
