#!/usr/bin/env python3
"""Per object: SSIM in its box on the whole-scene renders against the SSIM its
network measured on its own crop, for each selector's plan (session 40).

usage: inbox.py EVAL.json [SCENE]
For every (scene, device) prints one row per object: the crop SSIM of the
object's network under DP, Fairness and SLSQP (rows[].objects[].ssim) and
the object's in-box SSIM in the scene renders, mean over the held-out views
(rows[].views[].objects[].ssim). The shared network's objects carry its
crop figure. Markdown to stdout."""
import json, sys
from collections import defaultdict

d = json.load(open(sys.argv[1]))
only = sys.argv[2] if len(sys.argv) > 2 else None
methods = ('dp', 'fairness', 'slsqp')
for sc in d['scenes']:
    if only and sc['scene'] != only:
        continue
    net_of = {o['name']: o['network'] for o in sc['objects']}
    for dev in ('iphone13', 'pixel4'):
        crop, box, cfg = {}, {}, {}
        for r in sc['rows']:
            if r['device'] != dev or r['method'] not in methods:
                continue
            crop[r['method']] = {o['name']: o['ssim'] for o in r['objects']}
            cfg[r['method']] = {o['name']: (o['g'], o['p']) for o in r['objects']}
            m = defaultdict(list)
            for v in r['views']:
                for o in v['objects']:
                    m[o['object']].append(o['ssim'])
            box[r['method']] = {k: sum(x) / len(x) for k, x in m.items()}
        if not box:
            continue
        print(f'\n### {sc["scene"]} {dev}\n')
        print('| object (network) | crop SSIM DP / Fairness / SLSQP | in-box SSIM DP / Fairness / SLSQP | (g, p) DP / Fairness / SLSQP |')
        print('|---|---|---|---|')
        for obj in sorted(box['dp']):
            net = net_of.get(obj, obj)
            c = ' / '.join('%.4f' % crop[m].get(net, float('nan')) for m in methods)
            b = ' / '.join('%.4f' % box[m][obj] for m in methods)
            g = ' / '.join('(%d, %d)' % cfg[m][net] if net in cfg[m] else '–' for m in methods)
            print(f'| {obj} ({net}) | {c} | {b} | {g} |')
