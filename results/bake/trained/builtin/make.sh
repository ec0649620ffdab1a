#!/usr/bin/env bash
# A built-in object's trained sweep over the full (g, p) grid, at the
# evaluation's resolution (session 27; docs/baking.md, "Session 27"):
#   one object (default gear, Scene 2's and Scene 3's) rendered alone at
#   800 × 800 with the evaluation's 50 training + 12 held-out views;
#   three fields: the evaluation's budget (one level, 128³ × 800 steps at
#   8192 rays, TV every step, `eval::scale::Scale::train_settings`), two levels
#   (128:1000,256:2000) and `nerflex train`'s default
#   (128:1000,256:2000,384:4500, the lego and chair fields');
#   from each, g {16…256} × p {5…17} at the evaluation's 2 epochs, every
#   held-out view measured.
# Writes into WORK (default ./builtin-work): the capture, the fields, the
# bake cache; then copies each sweep here as OBJECT-<budget>-v<baker>.csv
# with its log and curves, and the fields' logs. About 80 min on 2 cores (the default field alone 14 min).
# FIELDS (environment) picks the fields, default all three; session 34 ran
# FIELDS=eval-budget for the nine objects without a sweep (sweeps of 9–40 min each, beside other jobs).
# Usage: [FIELDS="eval-budget ..."] results/bake/trained/builtin/make.sh [path/to/nerflex] [WORK] [OBJECT]
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
N="$(realpath "${1:-target/release/nerflex}")"
W="${2:-builtin-work}"
O="${3:-gear}"
mkdir -p "$W" && cd "$W"
[ -d cap ] || "$N" scene make --objects "$O" --views 50 --test-views 12 --size 800 --out cap > make.log
FIELDS="${FIELDS:-eval-budget two-levels default}"
has() { case " $FIELDS " in *" $1 "*) return 0 ;; *) return 1 ;; esac; }
mkdir -p $FIELDS
! has eval-budget || [ -f eval-budget/"$O".safetensors ] || "$N" train --capture cap --object "$O" --out eval-budget/"$O".safetensors \
  --levels 128:800 --batch 8192 --tv-every 1 --measure > train-eval-budget.log
! has two-levels || [ -f two-levels/"$O".safetensors ] || "$N" train --capture cap --object "$O" --out two-levels/"$O".safetensors \
  --levels 128:1000,256:2000 --measure > train-two-levels.log
! has default || [ -f default/"$O".safetensors ] || "$N" train --capture cap --object "$O" --out default/"$O".safetensors \
  --measure > train-default.log
V=v12 # the trained baker's version (bake::trained::TRAINED_BAKER_VERSION); v10 and v11: only the default field's sweep was re-run (sessions 29 and 30; session 31: tree's and session 32: text-panel's, default field only; v12: pawn (session 35) and ball with --choose-feature-res (session 36, by hand: docs/baking.md, "Session 36"), eval-budget field; from session 37 the sweep chooses the lattice by default: vase (37), box, torus, mug, spring (38), lattice and sponge (43), gear, tree, text-panel and lattice from two-levels (44), saved by hand as OBJECT-FIELD-choose-v12)
for f in $FIELDS; do
  "$N" bake --sweep --capture cap --object "$O" --field $f --grid 16,32,64,128,256 --patch 5,9,13,17 \
    --epochs 2 --csv "samples-$f.csv" --plots "plots-$f" --cache "cache-$f" > "sweep-$f.log"
  cp "samples-$f.csv" "$HERE/$O-$f-$V.csv"
  cp "sweep-$f.log" "$HERE/$O-sweep-$f-$V.log"
  cp "train-$f.log" "$HERE/$O-train-$f.log"
  cp "plots-$f/$O.png" "$HERE/$O-$f-$V.png"
done
