#!/usr/bin/env python3
"""The evaluation's profiler samples of two runs side by side (session 22).

usage: compare_samples.py OLD.csv NEW.csv [LABEL_OLD LABEL_NEW] > samples-compare.md
Both CSVs in the layout of results/bake/trained/samples-eval-paper.csv
(objects named SCENE.NETWORK, written by samples-eval-paper.py from an
eval.json). Writes, per scene, SSIM per (network, p) at each sampled g
for both runs, then counts the falls (a neighbour along g or p more than
0.002 SSIM below the smaller configuration) and each network's range
from its smallest to its largest sample."""
import csv, sys
from collections import defaultdict

def load(path):
    d = defaultdict(dict)
    with open(path) as f:
        for r in csv.DictReader(f):
            d[r['object']][(int(r['g']), int(r['p']))] = float(r['ssim'])
    return d

def falls(d):
    n = tot = 0
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

old, new = load(sys.argv[1]), load(sys.argv[2])
lo, ln = (sys.argv[3], sys.argv[4]) if len(sys.argv) > 4 else ('old', 'new')
scenes = sorted({k.split('.', 1)[0] for k in old} | {k.split('.', 1)[0] for k in new})
total = {lo: [0, 0], ln: [0, 0]}
for sc in scenes:
    nets = sorted({k for k in list(old) + list(new) if k.startswith(sc + '.')})
    gs = sorted({g for k in nets for d in (old, new) for g, _ in d.get(k, {})})
    ps = sorted({p for k in nets for d in (old, new) for _, p in d.get(k, {})})
    hdr = ' / '.join(str(g) for g in gs)
    print(f'\n### {sc}\n')
    print(f'| network | p | {lo} SSIM, g = {hdr} | {ln} SSIM, g = {hdr} |')
    print('|---|---|---|---|')
    for k in nets:
        for p in ps:
            cell = lambda d: ' / '.join(f'{d[(g, p)]:.4f}' if (g, p) in d else '–' for g in gs)
            o, w = old.get(k, {}), new.get(k, {})
            if any((g, p) in o or (g, p) in w for g in gs):
                print(f'| {k.split(".", 1)[1]} | {p} | {cell(o)} | {cell(w)} |')
    for label, d in ((lo, old), (ln, new)):
        n = t = 0; rng = []
        for k in nets:
            dk = d.get(k, {})
            a, b = falls(dk); n += a; t += b
            if dk:
                rng.append(f'{k.split(".", 1)[1]} {dk[max(dk)] - dk[min(dk)]:+.4f}')
        total[label][0] += n; total[label][1] += t
        print(f'\n{label}: {n} falls over {t} neighbouring pairs; largest minus smallest sample per network: ' + ', '.join(rng))
print('\n### All scenes\n')
for label in (lo, ln):
    print(f'- {label}: {total[label][0]} falls over {total[label][1]} neighbouring pairs')
