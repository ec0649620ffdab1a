#!/bin/bash
# same-time pair of two flag sets on one binary (BIN), one core each, cores swapped in round 2. args: tag "flagsA" "flagsB"; ROUNDS (default "1 2")
tag=$1; A="env X=1"; B="env X=1"; XA=$2; XB=$3; BIN=${BIN:-/work/runs/s53/nerflex-run}
one() { # core name prefix bin
  rm -rf o-$2
  /usr/bin/time -f "%e %U %S %R %M" -o t-$2.txt env RAYON_NUM_THREADS=1 taskset -c $1 $3 $4 bake $5 --capture /work/shared/data/nerf_synthetic_full/lego --field /work/runs/s52/fields/lego.safetensors --grid 128 --patch 17 --measure --max-test-views 10 --out o-$2 > l-$2.log 2>&1
}
for r in ${ROUNDS:-1 2}; do
  if [ $r = 1 ]; then ca=0; cb=1; else ca=1; cb=0; fi
  one $ca $tag-A$r "$A" $BIN "$XA" & one $cb $tag-B$r "$B" $BIN "$XB" & wait
  echo "$tag r$r A: $(cat t-$tag-A$r.txt) | $(grep 'time extract' l-$tag-A$r.log | cut -c15-) | $(grep "quality over" l-$tag-A$r.log | cut -c28-)" >> pair-results.txt
  echo "$tag r$r B: $(cat t-$tag-B$r.txt) | $(grep 'time extract' l-$tag-B$r.log | cut -c15-) | $(grep "quality over" l-$tag-B$r.log | cut -c28-)" >> pair-results.txt
done
