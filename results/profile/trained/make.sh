#!/usr/bin/env bash
# Regenerates results/profile/trained/ from the trained baker's samples:
#   results/bake/trained/samples-v12.csv        lego + chair at 800 × 800 (90 training views), baker version 12 (session 36,
#                                               chair's field re-trained at the default schedule; samples-v11.csv is session 30's
#                                               version 11, samples-v10.csv is session 29's version 10, samples-v9.csv session 28's
#                                               version 9, samples-v7.csv session 26's version 7)
#                                               (session 26; samples-v6.csv is session 23's version-6 sweep, samples.csv session 20's version 5),
#                                               g {16…256} × p {5…17}, `nerflex bake --sweep --field …`
#   results/bake/trained/samples-mesh-v6-radius2.csv  the same sweep with `--surface mesh` (session 25: version 6 with
#                                               the mesh's hull radius of 2 px; samples-mesh-v6.csv is session 24's
#                                               at 1 px, the regression;
#                                               samples-mesh.csv is session 15's)
#   results/bake/trained/samples-eval-paper.csv the paper-scale evaluation's profiler samples
#                                               (Scenes 1–4 + real, 9 per network, from results/eval/eval.json)
#                                               (written by results/bake/trained/samples-eval-paper.py)
#   results/bake/trained/builtin/*-*.csv        built-in objects alone at the evaluation's 800 × 800 and
#                                               50 + 12 views, g {16…256} × p {5…17}: gear from three field
#                                               budgets (session 27), tree (session 31) and text-panel (session 32) from the default field
#                                               (written by results/bake/trained/builtin/make.sh)
# Usage: results/profile/trained/make.sh [path/to/nerflex]
set -euo pipefail
cd "$(dirname "$0")/../../.."
N=${1:-target/release/nerflex}
S=results/bake/trained/samples-v12.csv
E=results/bake/trained/samples-eval-paper.csv
M=results/bake/trained/samples-mesh-v6-radius2.csv
O=results/profile/trained
"$N" profile fit --samples $S --out $O/profiles.json > /dev/null
"$N" profile fit --samples $E --out $O/profiles-eval-paper.json > /dev/null
"$N" profile accuracy --samples $S --json $O/accuracy_loo.json --plots $O/curves > $O/accuracy_loo.txt
"$N" profile accuracy --samples $S --train-on variable-step --json $O/accuracy_variable_step.json > $O/accuracy_variable_step.txt
"$N" profile accuracy --samples $S --train-on variable-step --max-size-mb 100 > $O/accuracy_variable_step_le100mb.txt
"$N" profile accuracy --samples $E --json $O/accuracy_eval_loo.json > $O/accuracy_eval_loo.txt
mkdir -p $O/mesh
"$N" profile fit --samples $M --out $O/mesh/profiles.json > /dev/null
"$N" profile accuracy --samples $M --json $O/mesh/accuracy_loo.json --plots $O/mesh/curves > $O/mesh/accuracy_loo.txt
"$N" profile accuracy --samples $M --train-on variable-step --json $O/mesh/accuracy_variable_step.json > $O/mesh/accuracy_variable_step.txt
mkdir -p $O/builtin
for f in results/bake/trained/builtin/*-*.csv; do
  b=$(basename "$f" .csv)
  "$N" profile accuracy --samples "$f" --train-on variable-step > $O/builtin/accuracy_variable_step-$b.txt
done
