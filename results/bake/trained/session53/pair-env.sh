#!/bin/bash
# same-time pair: config A on one core, B on the other, then swapped. args: tag "envA" "envB"
BIN=/work/runs/s53/nerflex-start
tag=$1; A=$2; B=$3
one() { # core name env
  rm -rf o-$2
  /usr/bin/time -f "%e %U %S %R %M" -o t-$2.txt env RAYON_NUM_THREADS=1 $3 taskset -c $1 $PRE $BIN bake --capture /work/shared/data/nerf_synthetic_full/lego --field /work/runs/s52/fields/lego.safetensors --grid 128 --patch 17 --measure --max-test-views 10 --out o-$2 > l-$2.log 2>&1
}
for r in 1 2; do
  if [ $r = 1 ]; then ca=0; cb=1; else ca=1; cb=0; fi
  one $ca $tag-A$r "$A" & one $cb $tag-B$r "$B" & wait
  echo "$tag r$r A: $(cat t-$tag-A$r.txt) | $(grep 'time extract' l-$tag-A$r.log | cut -c15-)" >> pair-results.txt
  echo "$tag r$r B: $(cat t-$tag-B$r.txt) | $(grep 'time extract' l-$tag-B$r.log | cut -c15-)" >> pair-results.txt
done
