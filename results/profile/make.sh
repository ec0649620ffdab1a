#!/usr/bin/env bash
# Regenerates every file of results/profile/ from the bake sweep's samples CSV
# (results/bake/samples.csv). Usage: results/profile/make.sh [path/to/nerflex]
set -euo pipefail
cd "$(dirname "$0")/../.."
N=${1:-target/release/nerflex}
S=results/bake/samples.csv
O=results/profile
"$N" profile fit --samples $S --out $O/profiles.json > /dev/null
acc() { # name, flags…
    local name=$1
    shift
    "$N" profile accuracy --samples $S "$@" > $O/$name.txt
}
acc accuracy_loo --json $O/accuracy_loo.json
acc accuracy_loo_le100mb --max-size-mb 100 --json $O/accuracy_loo_le100mb.json
acc accuracy_variable_step --train-on variable-step --json $O/accuracy_variable_step.json
acc accuracy_variable_step_le100mb --train-on variable-step --max-size-mb 100
acc accuracy_variable_step_double --train-on variable-step --step double
for f in volume surface; do
    acc accuracy_loo_$f --family $f
    acc accuracy_loo_le100mb_$f --max-size-mb 100 --family $f
    acc accuracy_variable_step_$f --train-on variable-step --family $f
done
{
    "$N" plan --scene examples/scenes/real_profiles.json --device iphone13
    "$N" plan --scene examples/scenes/real_profiles.json --device pixel4
} > $O/plan_real_profiles.txt
