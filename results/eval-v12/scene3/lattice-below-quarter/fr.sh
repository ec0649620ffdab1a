#!/bin/bash
cd /work/runs/s39
C=/work/runs/s39/eval-scene3/scenes/scene3/segment/gear
F=/work/runs/s37/store4/fields/gear-f3b21d195a441546f.safetensors
for fr in 100 50; do
  /usr/bin/time -v ./nerflex bake --field $F --capture $C --grid 64 --patch 9 --epochs 2 --feature-res $fr --measure --out /work/runs/s39/gear-fr$fr > gear-fr$fr.log 2>&1
  echo rc=$? >> gear-fr$fr.log
done
