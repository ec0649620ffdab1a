#!/usr/bin/env python3
"""Squared error of two plans' whole-scene renders split by object (session 40).

usage: objsplit.py SCENE_DIR A_PLAN B_PLAN [VIEWS]
SCENE_DIR is an eval work folder's scenes/<scene> (capture/test/r_N.png,
r_N_mask.png, scene.json; renders/<plan>/test_N.png). Each pixel goes to the
object whose mask value it carries; background pixels within 3 px of an object
go to that object's "edge"; the rest is "background". Prints, per region, the
pixel count and each plan's summed squared error (8-bit RGB) over the views,
and B − A. Pure Python (no imaging library on this machine)."""
import json, os, sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '../../bake/trained/builtin/session38'))
import png_rgb as png

scene, pa, pb = sys.argv[1:4]
views = int(sys.argv[4]) if len(sys.argv) > 4 else 12
names = {o['mask_value']: o['name'] for o in json.load(open(os.path.join(scene, 'capture/scene.json')))['objects']}
acc = {}
for v in range(views):
    ref = png.read(os.path.join(scene, f'capture/test/r_{v}.png'))
    mask = png.read(os.path.join(scene, f'capture/test/r_{v}_mask.png'))
    a = png.read(os.path.join(scene, f'renders/{pa}/test_{v}.png'))
    b = png.read(os.path.join(scene, f'renders/{pb}/test_{v}.png'))
    H, W = len(ref), len(ref[0])
    lab = [[mask[y][x][0] for x in range(W)] for y in range(H)]
    # nearest object label within 3 px for background pixels (edges)
    edge = [[0] * W for _ in range(H)]
    for y in range(H):
        for x in range(W):
            if lab[y][x]:
                continue
            for yy in range(max(0, y - 3), min(H, y + 4)):
                row = lab[yy]
                for xx in range(max(0, x - 3), min(W, x + 4)):
                    if row[xx]:
                        edge[y][x] = row[xx]
                        break
                if edge[y][x]:
                    break
    for y in range(H):
        for x in range(W):
            l = lab[y][x]
            key = names.get(l, f'mask{l}') if l else (names.get(edge[y][x], '?') + ' edge' if edge[y][x] else 'background')
            r = ref[y][x]
            ea = sum((a[y][x][k] - r[k]) ** 2 for k in range(3))
            eb = sum((b[y][x][k] - r[k]) ** 2 for k in range(3))
            s = acc.setdefault(key, [0, 0, 0])
            s[0] += 1; s[1] += ea; s[2] += eb
    print(f'view {v} done', file=sys.stderr)
print(f'| region | pixels | {pa} SSE | {pb} SSE | B − A |')
print('|---|---|---|---|---|')
for k in sorted(acc, key=lambda k: -abs(acc[k][2] - acc[k][1])):
    n, ea, eb = acc[k]
    print(f'| {k} | {n} | {ea/1e6:.2f} M | {eb/1e6:.2f} M | {(eb-ea)/1e6:+.2f} M |')
