#!/bin/bash
cd /work/runs/s39
while pgrep -f fr.sh > /dev/null; do sleep 5; done
run() { # object field fr
  C=/work/runs/s39/eval-scene3/scenes/scene3/segment/$1
  /usr/bin/time -v ./nerflex bake --field $2 --capture $C --grid 64 --patch 9 --epochs 2 --feature-res $3 --measure --out /work/runs/s39/$1-fr$3 > $1-fr$3.log 2>&1
  echo rc=$? >> $1-fr$3.log
}
G=/work/runs/s37/store4/fields/gear-f3b21d195a441546f.safetensors
L=/work/runs/s37/store4/fields/lattice-f2704739ce6db1e31.safetensors
run gear $G 25
run lattice $L 70
run lattice $L 35
run gear $G 399
