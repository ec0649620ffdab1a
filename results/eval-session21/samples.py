#!/usr/bin/env python3
"""Session 21: one scene's profiler samples from a bake store beside
session 19's (results/bake/trained/samples-eval-paper.csv).

usage: samples.py STORE SCENE > samples-SCENE.md
Reads STORE/*/sample.json (one per bake the profiler measured; every
network of SCENE is named by its object), writes a markdown table of
SSIM per (network, p, g) for both runs and counts the falls along g and
p (a fall: more than 0.002 SSIM below the smaller neighbour)."""
import csv, glob, json, os, sys
from collections import defaultdict

store, scene = sys.argv[1], sys.argv[2]
root = os.path.dirname(os.path.abspath(__file__))
old = defaultdict(dict)
with open(os.path.join(root, '..', 'bake', 'trained', 'samples-eval-paper.csv')) as f:
    for r in csv.DictReader(f):
        sc, net = r['object'].split('.', 1)
        if sc == scene:
            old[net][(int(r['g']), int(r['p']))] = float(r['ssim'])
new = defaultdict(dict)
for path in glob.glob(os.path.join(store, '*', 'sample.json')):
    s = json.load(open(path))
    # Only the profiler's sample points (the plans' bakes write samples
    # too): the same (g, p) as session 19's rows.
    if (s['g'], s['p']) in old.get(s['object'], {}):
        new[s['object']][(s['g'], s['p'])] = s['ssim']

def falls(d):
    n, tot = 0, 0
    gs = sorted({g for g, _ in d}); ps = sorted({p for _, p in d})
    for p in ps:
        for a, b in zip(gs, gs[1:]):
            if (a, p) in d and (b, p) in d:
                tot += 1; n += d[(a, p)] - d[(b, p)] > 0.002
    for g in gs:
        for a, b in zip(ps, ps[1:]):
            if (g, a) in d and (g, b) in d:
                tot += 1; n += d[(g, a)] - d[(g, b)] > 0.002
    return n, tot

print(f'| {scene} network | p | session 19 SSIM, g = 16 / 32 / 64 | session 21 SSIM, g = 16 / 32 / 64 |')
print('|---|---|---|---|')
for net in sorted(old):
    for p in (3, 10, 17):
        cell = lambda d: ' / '.join(f'{d[(g, p)]:.4f}' if (g, p) in d else '–' for g in (16, 32, 64))
        print(f'| {net} | {p} | {cell(old[net])} | {cell(new[net])} |')
for name, d in (('session 19', old), ('session 21', new)):
    n = t = 0
    rng = []
    for net in sorted(d):
        a, b = falls(d[net]); n += a; t += b
        if (16, 3) in d[net] and (64, 17) in d[net]:
            rng.append((net, d[net][(64, 17)] - d[net][(16, 3)]))
    print(f'\n{name}: {n} falls over {t} neighbouring pairs; (64, 17) − (16, 3) per network: ' +
          ', '.join(f'{k} {r:+.4f}' for k, r in rng))
