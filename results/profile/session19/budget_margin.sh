#!/usr/bin/env bash
# Session 19: does `nerflex plan --size-margin` keep DP plans of lego + chair
# within budget in MEASURED bytes? For each geometry (planes, mesh), budget
# and margin (0 and 11.3 %, the worst under-prediction of the variable-step
# fit on the session-18 sweep, docs/profiler.md), the DP plan from today's
# profiles (results/profile/trained/{,mesh/}profiles.json) and the sweep's
# measured file bytes of the same configurations
# (results/bake/trained/samples*.csv), as a share of the budget.
# Usage: results/profile/session19/budget_margin.sh [path/to/nerflex] > results/profile/session19/budget_margin.txt
# (GEOS and MARGINS, space-separated, replace the geometries and margins,
# PLANES_SAMPLES the planes' sweep: results/profile/session20/ and session24/
# budget_margin.sh set them.)
set -euo pipefail
cd "$(dirname "$0")/../../.."
N=${1:-target/release/nerflex}
echo "geometry margin  budget  planned-against MB  predicted MB  measured MB  measured − budget  predicted SSIM  plan (object(g,p))"
for geo in ${GEOS:-planes mesh}; do
    S=${PLANES_SAMPLES:-results/bake/trained/samples.csv}
    P=results/profile/trained/profiles.json
    if [ $geo = mesh ]; then
        S=results/bake/trained/samples-mesh.csv
        P=results/profile/trained/mesh/profiles.json
    fi
    for margin in ${MARGINS:-0 11.3}; do
        for b in 50 100 150 200 300 400 600; do
            "$N" plan --scene $P --device iphone13 --budget-mb $b --size-margin $margin --json |
                jq -r '(.budget_bytes | tostring) as $pb | (.total_quality | tostring) as $q
                       | .objects[] | [.name, .g, .p, .size_bytes, $pb, $q] | @csv' | tr -d '"' |
                awk -F, -v b=$b -v geo=$geo -v margin=$margin '
                    NR == FNR { if (FNR > 1) m[$1 "," $2 "," $3] = $4; next }
                    { k = $1 "," $2 "," $3
                      if (!(k in m)) { print "no sweep sample for " k > "/dev/stderr"; exit 1 }
                      pred += $4; meas += m[k]; pb = $5; q = $6; plan = plan " " $1 "(" $2 "," $3 ")" }
                    END { printf "%-8s %6s  %6d  %18.2f  %12.2f  %11.2f  %+16.1f %%  %14.4f  %s\n",
                          geo, margin, b, pb / 1e6, pred / 1e6, meas / 1e6,
                          100 * (meas / 1e6 - b) / b, q, plan }' $S -
        done
    done
done
