#!/usr/bin/env bash
# Session 18: do DP plans of lego + chair respect the budget, measured on the
# sweep the profiles were fitted to? For each geometry (planes, mesh) and each
# budget, the DP plan (iphone13 device, --budget-mb B) from the profiles
# before session 18 (commit 8750313, the surface law) and after (the quads
# law); beside the predicted total, the sweep's MEASURED file bytes of the same
# configurations (results/bake/trained/samples*.csv), as a share of the budget.
# Usage: results/profile/session18/budget_check.sh [path/to/nerflex] > results/profile/session18/budget_check.txt
set -euo pipefail
cd "$(dirname "$0")/../../.."
N=${1:-target/release/nerflex}
OLD=8750313
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
git show $OLD:results/profile/trained/profiles.json > "$T/old-planes.json"
git show $OLD:results/profile/trained/mesh/profiles.json > "$T/old-mesh.json"
cp results/profile/trained/profiles.json "$T/new-planes.json"
cp results/profile/trained/mesh/profiles.json "$T/new-mesh.json"
echo "geometry law     budget  predicted MB  measured MB  measured − budget  plan (object(g,p))"
for geo in planes mesh; do
    S=results/bake/trained/samples.csv
    [ $geo = mesh ] && S=results/bake/trained/samples-mesh.csv
    for law in old new; do
        for b in 50 100 150 200 300 400 600; do
            "$N" plan --scene "$T/$law-$geo.json" --device iphone13 --budget-mb $b --json |
                jq -r '.objects[] | [.name, .g, .p, .size_bytes] | @csv' | tr -d '"' |
                awk -F, -v b=$b -v geo=$geo -v law=$law '
                    NR == FNR { if (FNR > 1) m[$1 "," $2 "," $3] = $4; next }
                    { k = $1 "," $2 "," $3
                      if (!(k in m)) { print "no sweep sample for " k > "/dev/stderr"; exit 1 }
                      pred += $4; meas += m[k]; plan = plan " " $1 "(" $2 "," $3 ")" }
                    END { printf "%-8s %-7s %6d  %12.2f  %11.2f  %+16.1f %%  %s\n",
                          geo, (law == "old" ? "surface" : "quads"), b, pred / 1e6, meas / 1e6,
                          100 * (meas / 1e6 - b) / b, plan }' $S -
        done
    done
done
