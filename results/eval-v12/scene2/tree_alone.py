#!/usr/bin/env python3
"""Session 40's experiment, kept as run (its paths are that session's work folders, out of git):
Scene 2's shared (tree) network rendered alone from the scene's 12 held-out cameras at the
configurations DP and Fairness chose, and the squared error on the tree's pixels (instance
mask) against the ground truth, beside the same pixels in the whole-scene renders.
Output: tree-alone.md. Needs the scene's eval work folder and the store."""
import json, os, subprocess, sys
sys.path.insert(0, '/work/main/results/bake/trained/builtin/session38')
import png_rgb as png
N='/work/main/target/release/nerflex'; C='/work/runs/s40/eval-scene2/scenes/scene2/capture'; D='/work/runs/s37/store4'
assets={'dp32_17':D+'/shared-g32-p17-td77d105a708d3fe1','f96_17':D+'/shared-g96-p17-t9195107a1328beb6','dp16_15':D+'/shared-g16-p15-teecb628cb88a1134','f96_11':D+'/shared-g96-p11-t7aa9b18a46a1e3db'}
label={o['name']:o['mask_value'] for o in json.load(open(C+'/scene.json'))['objects']}['tree']
R='/work/runs/s40/eval-scene2/scenes/scene2/renders'
acc={k:0 for k in list(assets)+['scene_dp_iphone','scene_f_iphone','scene_dp_pixel','scene_f_pixel']}
npx=0
for v in range(12):
    ref=png.read(f'{C}/test/r_{v}.png'); m=png.read(f'{C}/test/r_{v}_mask.png')
    pix=[(y,x) for y in range(len(m)) for x in range(len(m[0])) if m[y][x][0]==label]
    npx+=len(pix)
    imgs={}
    for k,a in assets.items():
        subprocess.run([N,'render','--asset',a+'/asset','--transforms',C+'/transforms_test.json','--frame',str(v),'--size','800','--out','r.png'],check=True,capture_output=True)
        imgs[k]=png.read('r.png')
    imgs['scene_dp_iphone']=png.read(f'{R}/02-nerflex-dp-iphone13/test_{v}.png')
    imgs['scene_f_iphone']=png.read(f'{R}/04-fairness-iphone13/test_{v}.png')
    imgs['scene_dp_pixel']=png.read(f'{R}/03-nerflex-dp-pixel4/test_{v}.png')
    imgs['scene_f_pixel']=png.read(f'{R}/05-fairness-pixel4/test_{v}.png')
    for k,im in imgs.items():
        acc[k]+=sum(sum((im[y][x][c]-ref[y][x][c])**2 for c in range(3)) for y,x in pix)
    print('view',v,file=sys.stderr)
print('tree-labelled pixels over 12 views:', npx)
for k,v in acc.items(): print(f'{k}: SSE {v/1e6:.2f} M')
