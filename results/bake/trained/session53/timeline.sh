#!/bin/bash
# usage: timeline.sh BIN OUTDIR LOG
BIN=$1; OUT=$2; LOG=$3
rm -rf $OUT
start=$(date +%s.%N)
( $BIN bake --capture /work/shared/data/nerf_synthetic_full/lego --field /work/runs/s52/fields/lego.safetensors --grid 128 --patch 17 --measure --max-test-views 10 --out $OUT 2>&1 | while IFS= read -r l; do printf '%.2f %s\n' $(echo "$(date +%s.%N) - $start" | bc) "$l"; done > $LOG ) &
sleep 0.3
pid=$(pgrep -n -f " bake --capture")
tck=$(getconf CLK_TCK)
prev=0
while kill -0 $pid 2>/dev/null; do
  s=$(awk "{print \$14+\$15}" /proc/$pid/stat 2>/dev/null) || break; rss=$(awk "/VmRSS/{print \$2}" /proc/$pid/status)
  now=$(echo "$(date +%s.%N) - $start" | bc)
  echo "$now $s $rss" >> $LOG.cpu
  sleep 0.5
done
wait
