#!/usr/bin/env bash
# Session 24 (baker version 6 sweep, results/bake/trained/samples-v6.csv, which
# results/profile/trained/make.sh now fits): session 19's check of `nerflex plan
# --size-margin` against MEASURED bytes, planes only, at margins 0 and 11.3 %
# (the worst under-prediction of the variable-step fit on the version-6 sweep,
# results/profile/trained/accuracy_variable_step.txt).
# Usage: results/profile/session24/budget_margin.sh [path/to/nerflex] > results/profile/session24/budget_margin.txt
set -euo pipefail
GEOS=planes MARGINS="0 11.3" PLANES_SAMPLES=results/bake/trained/samples-v6.csv \
    exec "$(dirname "$0")/../session19/budget_margin.sh" "$@"
