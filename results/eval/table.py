#!/usr/bin/env python3
"""The README's table of the paper-scale evaluation, from a run's eval.json and report.md (session 40).

usage: table.py [DIR]   (DIR holds eval.json and report.md; default results/eval)
One row per (scene, method): SSIM with its 95 % interval per device (read from
the report's means tables), PSNR, LPIPS, baked MB and mean FPS per device
(one figure where both devices agree). Markdown to stdout."""
import json, os, re, sys

root = sys.argv[1] if len(sys.argv) > 1 else 'results/eval'
d = json.load(open(os.path.join(root, 'eval.json')))
ci, cur = {}, None
for line in open(os.path.join(root, 'report.md'), encoding='utf-8'):
    s = line.strip()
    if s.startswith('### '):
        cur = s[4:]
    if s.startswith('## Real capture'):
        cur = 'lego+chair'
    m = re.match(r'\| (iphone13|pixel4) \| ([^|]+) \| (\d+) \| ([0-9.]+) \[([0-9.]+), ([0-9.]+)\]', s)
    if m and cur:
        ci[(cur, m.group(1), m.group(2).strip())] = '%s [%s, %s]' % m.group(4, 5, 6)
names = {'single': 'Single-NeRF', 'block': 'Block-NeRF', 'dp': 'NeRFlex (DP)', 'fairness': 'Fairness', 'slsqp': 'SLSQP'}


def fps(r):
    if r['load_failure']:
        return '**load fails** (0)'
    return '%.1f' % r['mean_fps'] + (' (over soft limit)' if r['over_soft_limit'] else '')


def pair(a, b, f):
    x, y = f(a), f(b)
    return x if x == y else x + ' / ' + y


print('| scene | method | SSIM iPhone 13 [95 %] | SSIM Pixel 4 [95 %] | PSNR dB (iPhone / Pixel) | LPIPS | baked MB (iPhone / Pixel) | mean FPS (iPhone / Pixel) |')
print('|---|---|---|---|---|---|---|---|')
scenes = [(s['scene'], s['rows']) for s in d['scenes']]
if d.get('real'):
    scenes.append(('lego+chair', d['real']['rows']))
# Scene 3's DP cells are the device files' calibration cells (docs/device.md).
for name, rows in scenes:
    for m in names:
        rr = {r['device']: r for r in rows if r['method'] == m}
        a, b = rr['iphone13'], rr['pixel4']
        if a['error']:
            print(f'| {name} | {names[m]} | – | – | – | – | – | no plan |')
            continue
        fa = fps(a) + (' (calibrated)' if name == 'scene3' and m == 'dp' else '')
        fb = fps(b) + (' (calibrated)' if name == 'scene3' and m == 'dp' else '')
        print(f"| {name} | {names[m]} | {ci.get((name, 'iphone13', names[m]), '?')} | {ci.get((name, 'pixel4', names[m]), '?')} "
              f"| {pair(a, b, lambda r: '%.2f' % r['quality']['psnr'])} | {pair(a, b, lambda r: '%.4f' % r['quality']['lpips'])} "
              f"| {pair(a, b, lambda r: '%.1f' % (r['file_bytes'] / 1e6))} | {fa} / {fb} |")
