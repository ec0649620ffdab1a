#!/usr/bin/env python3
"""Does the DP's objective predict the scene's SSIM? (session 40)

usage: objective_check.py EVAL.json SEG_DIR
SEG_DIR holds each scene's segmentation.json as <scene>.json (this folder's
segmentation/, copied from the run's scenes/<scene>/segment/): its groups'
mean zoom says how much a dedicated network's crop enlarges its object; the
shared network's views are the original frames, zoom 1.
For each scene, device and baseline selector, compares the measured
difference of whole-scene SSIM (selector − DP) with two predictions from
the networks' own measured SSIM at the realised plans:
  equal   = mean over networks of (selector − DP)   (the paper's objective)
  zoom    = sum over networks of (selector − DP) / zoom²
            (each network's SSIM scaled by its share of a scene frame).
Prints a markdown table and each prediction's correlation and sign
agreement with the measurement."""
import json, math, sys

d = json.load(open(sys.argv[1]))
seg_dir = sys.argv[2]
rows_out, meas, eqs, zs = [], [], [], []
for sc in d['scenes']:
    seg = json.load(open(f"{seg_dir}/{sc['scene']}.json"))
    zoom = {g['folder']: g.get('mean_zoom', 1.0) for g in seg['groups']}
    for dev in ('iphone13', 'pixel4'):
        r = {x['method']: x for x in sc['rows'] if x['device'] == dev}
        dp = {o['name']: o['ssim'] for o in r['dp']['objects']}
        for m in ('fairness', 'slsqp'):
            o = {x['name']: x['ssim'] for x in r[m]['objects']}
            eq = sum(o[n] - dp[n] for n in dp) / len(dp)
            z = sum((o[n] - dp[n]) / zoom.get(n, 1.0) ** 2 for n in dp)
            ms = r[m]['quality']['ssim'] - r['dp']['quality']['ssim']
            meas.append(ms); eqs.append(eq); zs.append(z)
            rows_out.append(f"| {sc['scene']} | {dev} | {m} | {ms:+.4f} | {eq:+.4f} | {z:+.4f} |")


def corr(a, b):
    ma, mb = sum(a) / len(a), sum(b) / len(b)
    c = sum((x - ma) * (y - mb) for x, y in zip(a, b))
    return c / math.sqrt(sum((x - ma) ** 2 for x in a) * sum((y - mb) ** 2 for y in b))


def signs(a, b, eps=0.00005):
    pairs = [(x, y) for x, y in zip(a, b) if abs(x) > eps]
    return sum((x > 0) == (y > 0) for x, y in pairs), len(pairs)


print('| scene | device | selector | measured scene SSIM, selector − DP | equal-weight prediction (the paper\'s objective) | zoom²-weighted prediction |')
print('|---|---|---|---|---|---|')
print('\n'.join(rows_out))
print()
for name, p in (('equal-weight', eqs), ('zoom²-weighted', zs)):
    s, n = signs(meas, p)
    err = sum(abs(x - y) for x, y in zip(meas, p)) / len(p)
    print(f'- {name}: Pearson r = {corr(meas, p):+.2f} over {len(p)} cells; sign agrees in {s} of {n} cells with |measured| > 0.00005; mean |error| {err:.4f}')
