#!/usr/bin/env python3
"""Pooled Spearman's rho of the segmentation's two frequency readings against
the gain of a dedicated network, over the objects of several eval reports
(permutation p, 20000 shuffles, seed 1)."""
import random, sys
rows = []
for f in sys.argv[1:]:
    md = open(f).read()
    sec = md[md.index('## Does the segmentation'):]
    for l in sec.split('\n'):
        c = [x.strip() for x in l.strip('|').split('|')]
        if len(c) == 6 and c[0].startswith('scene') and c[0] != 'scene':
            rows.append((c[0], c[1], float(c[3]), float(c[4]), float(c[5].split()[0])))
def rank(v):
    s = sorted(range(len(v)), key=lambda i: v[i]); r = [0] * len(v); i = 0
    while i < len(v):
        j = i
        while j + 1 < len(v) and v[s[j + 1]] == v[s[i]]: j += 1
        for k in range(i, j + 1): r[s[k]] = (i + j) / 2
        i = j + 1
    return r
def rho(a, b):
    ra, rb = rank(a), rank(b); n = len(a); ma = sum(ra) / n; mb = sum(rb) / n
    num = sum((x - ma) * (y - mb) for x, y in zip(ra, rb))
    den = (sum((x - ma) ** 2 for x in ra) * sum((y - mb) ** 2 for y in rb)) ** .5
    return num / den
g = [r[4] for r in rows]
random.seed(1)
for name, idx in (('cycles per object diameter', 2), ('cycles per pixel', 3)):
    x = [r[idx] for r in rows]; r0 = rho(x, g); cnt = 0; N = 20000
    for _ in range(N):
        y = g[:]; random.shuffle(y)
        if abs(rho(x, y)) >= abs(r0) - 1e-12: cnt += 1
    print(f'{name}: rho = {r0:+.3f} over {len(rows)} objects, permutation p = {cnt / N:.4f}')
