#!/bin/bash
# alternating allocator experiment on one binary
BIN=/work/runs/s53/nerflex-start
run() { # name env...
  name=$1; shift
  rm -rf o-$name
  /usr/bin/time -f "%e %U %S %R %M" -o t-$name.txt env "$@" $BIN bake --capture /work/shared/data/nerf_synthetic_full/lego --field /work/runs/s52/fields/lego.safetensors --grid 128 --patch 17 --measure --max-test-views 10 --out o-$name > l-$name.log 2>&1
  echo "$r $name $(cat t-$name.txt) | $(grep 'time extract' l-$name.log | cut -c15-) | $(grep 'quality over' l-$name.log)" >> alloc-results.txt
}
for r in 1 2; do
  run base X=1
  run glibc GLIBC_TUNABLES=glibc.malloc.mmap_threshold=1073741824
  run mi LD_PRELOAD=/usr/lib/x86_64-linux-gnu/libmimalloc.so.2 MIMALLOC_PURGE_DELAY=-1
  run je LD_PRELOAD=/usr/lib/x86_64-linux-gnu/libjemalloc.so.2 MALLOC_CONF=dirty_decay_ms:-1,muzzy_decay_ms:-1,thp:always
done
echo done >> alloc-results.txt
