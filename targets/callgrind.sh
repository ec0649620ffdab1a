#!/usr/bin/env bash
# Instruction counts on the host (x86-64) of one MCK solve and one shaded
# pixel, measured with valgrind's callgrind (deterministic: the same binary
# gives the same counts on every run). Usage: targets/callgrind.sh
#
# Builds targets/callgrind (the firmware's workload, same tables, same
# lego MLP) and counts, per operation, the instructions executed inside the
# named function and everything it calls (--toggle-collect).
set -euo pipefail
cd "$(dirname "$0")/callgrind"
command -v valgrind >/dev/null || { echo "valgrind is not installed (apt-get install valgrind)" >&2; exit 1; }
cargo build --release --locked -q
bin=target/release/nerflex-count
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

count() { # mode function -> prints "Ir"
    valgrind --tool=callgrind --callgrind-out-file="$out/$1.out" --collect-atstart=no \
        "--toggle-collect=*$2*" "$bin" "$1" >"$out/$1.txt" 2>"$out/$1.err"
    awk '/^summary:/ {print $2}' "$out/$1.out"
}

echo "| operation | instructions (Ir) | result |"
echo "|---|---|---|"
ir=$(count profiles count_profiles)
echo "| five fitted profiles → 5 × 45 configurations (fixed-point profiler) | $ir ($((ir / 225)) per configuration) | $(head -1 "$out/profiles.txt") … |"
for dev in iphone13 pixel4; do
    ir=$(count "solve-$dev" count_solve)
    echo "| one MCK solve, 5 objects × 45 configurations, $dev budget in 0.1 MB units | $ir | $(cat "$out/solve-$dev.txt") |"
done
ir=$(count pixel count_pixel)
echo "| one shaded pixel (fixed-point MLP, 480 multiply-adds) | $ir | $(cat "$out/pixel.txt") |"
ir=$(count narrow-pixel count_narrow_pixel)
echo "| one shaded pixel (narrow MLP, 16-bit, 496 multiply-adds incl. padding) | $ir | $(cat "$out/narrow-pixel.txt") |"
ir=$(count narrow-batch count_narrow_batch)
echo "| 8 pixels through the AVX2 narrow batch (inputs packed) | $ir ($((ir / 8)) per pixel) | $(cut -c1-60 "$out/narrow-batch.txt") … |"
ir=$(count tile count_tile)
echo "| 16 × 16 tile incl. per-pixel inputs | $ir ($((ir / 256)) per pixel) | $(cat "$out/tile.txt") |"
