#!/usr/bin/env python3
"""The shared network's sample bakes scored in its objects' box (session 40).

usage: treebox.py NERFLEX GROUP_DIR STORE_DIR... > table.md
GROUP_DIR is an eval work folder's segment/<group> (test/r_N.png, r_N_mask.png,
transforms_test.json); each STORE_DIR a store entry (asset/, sample.json).
Renders each entry from every held-out view, crops render and truth to the
box of the group's objects (mask != 0, 4 px margin, as the report's in-box
SSIM, `pipeline::views::object_box`, without its 16-px minimum side), and
scores the crops with `nerflex metrics`. Prints per entry the
whole-frame SSIM the profiler measured (sample.json) and the in-box mean."""
import json, os, subprocess, sys, tempfile
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '../../bake/trained/builtin/session38'))
import png_rgb as png

nerflex, group, stores = sys.argv[1], sys.argv[2], sys.argv[3:]
views = len(json.load(open(os.path.join(group, 'transforms_test.json')))['frames'])
tmp = tempfile.mkdtemp()
boxes, truths = [], []
for v in range(views):
    m = png.read(os.path.join(group, f'test/r_{v}_mask.png'))
    ys = [y for y, row in enumerate(m) if any(px[0] for px in row)]
    xs = [x for x in range(len(m[0])) if any(m[y][x][0] for y in ys)]
    H, W = len(m), len(m[0])
    b = (max(0, min(ys) - 4), min(H, max(ys) + 5), max(0, min(xs) - 4), min(W, max(xs) + 5))
    boxes.append(b)
    t = png.read(os.path.join(group, f'test/r_{v}.png'))
    tp = os.path.join(tmp, f'truth_{v}.png')
    png.write(tp, [row[b[2]:b[3]] for row in t[b[0]:b[1]]])
    truths.append(tp)
print('| entry | (g, p) | whole-frame SSIM (profiler) | in-box SSIM, mean over views | in-box PSNR dB |')
print('|---|---|---|---|---|')
for st in stores:
    s = json.load(open(os.path.join(st, 'sample.json'))) if os.path.exists(os.path.join(st, 'sample.json')) else {}
    bake = json.load(open(os.path.join(st, 'bake.json')))
    ss, ps = [], []
    for v in range(views):
        r = os.path.join(tmp, 'r.png')
        subprocess.run([nerflex, 'render', '--asset', os.path.join(st, 'asset'), '--transforms',
                        os.path.join(group, 'transforms_test.json'), '--frame', str(v), '--size', '800',
                        '--out', r], check=True, capture_output=True)
        b = boxes[v]
        img = png.read(r)
        rc = os.path.join(tmp, 'rc.png')
        png.write(rc, [row[b[2]:b[3]] for row in img[b[0]:b[1]]])
        out = subprocess.run([nerflex, 'metrics', '--json', rc, truths[v]], capture_output=True, text=True, check=True)
        j = json.loads(out.stdout)
        ss.append(j['ssim']); ps.append(j['psnr'])
    g, p = s.get('g', bake.get('grid')), s.get('p', bake.get('patch'))
    print(f"| {os.path.basename(st)} | ({g}, {p}) | {s.get('ssim', float('nan')):.4f} | {sum(ss)/len(ss):.4f} | {sum(ps)/len(ps):.2f} |", flush=True)
