#!/usr/bin/env bash
# Session 26 (baker version 7 sweep, results/bake/trained/samples-v7.csv, which
# results/profile/trained/make.sh now fits): session 19's check of `nerflex plan
# --size-margin` against MEASURED bytes, planes only, at margins 0 and 11.3 %
# (the default margin; the variable-step fit's worst under-prediction on the
# version-7 sweep is 10.8 %, results/profile/trained/accuracy_variable_step.txt).
# Usage: results/profile/session26/budget_margin.sh [path/to/nerflex] > results/profile/session26/budget_margin.txt
set -euo pipefail
GEOS=planes MARGINS="0 11.3" PLANES_SAMPLES=results/bake/trained/samples-v7.csv \
    exec "$(dirname "$0")/../session19/budget_margin.sh" "$@"
