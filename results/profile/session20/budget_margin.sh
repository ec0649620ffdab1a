#!/usr/bin/env bash
# Session 20 (baker version 5 sweep): session 19's check of `nerflex plan
# --size-margin` against MEASURED bytes, on the planes only (the mesh did not
# change), at margins 0 and 13.3 % (the worst under-prediction of the
# variable-step fit on the session-20 sweep, docs/profiler.md).
# Usage: results/profile/session20/budget_margin.sh [path/to/nerflex] > results/profile/session20/budget_margin.txt
set -euo pipefail
GEOS=planes MARGINS="0 13.3" exec "$(dirname "$0")/../session19/budget_margin.sh" "$@"
