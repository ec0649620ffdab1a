#!/usr/bin/env python3
"""The area-weighted objective against the paper's, scene by scene (session 41).

usage: compare.py BASE_EVAL.json AREA_EVAL.json [AREA_EVAL.json ...]
BASE is the run with the paper's objective (results/eval/eval.json), each
AREA a `nerflex eval --objective area` run on the same store (same bakes
for the same configurations, same held-out views). For each scene and
device prints:
  1. each optimising selector's plan and whole-scene SSIM / PSNR / LPIPS
     under both objectives, and the paired difference area − mean in SSIM
     with a 95 % percentile bootstrap interval over the held-out views;
  2. under the area objective: DP − Fairness, DP − SLSQP, DP − Block and
     DP − Single in SSIM with the same intervals (the paper's claims).
Fairness, Block and Single plan the same under both objectives; their
rows come from each run's own measurement."""
import json, random, sys

RESAMPLES, SEED = 2000, 7


def rows(path):
    d = json.load(open(path))
    out = {}
    for sc in d['scenes']:
        for r in sc['rows']:
            out[(sc['scene'], r['device'], r['method'])] = r
    return out


def ci(diffs):
    rng = random.Random(SEED)
    n = len(diffs)
    means = sorted(sum(diffs[rng.randrange(n)] for _ in range(n)) / n for _ in range(RESAMPLES))
    return sum(diffs) / n, means[int(0.025 * RESAMPLES)], means[int(0.975 * RESAMPLES) - 1]


def paired(a, b, key='ssim'):
    va = {v['view']: v[key] for v in a['views']}
    vb = {v['view']: v[key] for v in b['views']}
    return ci([va[k] - vb[k] for k in sorted(va) if k in vb])


def fmt(m, lo, hi):
    star = ' *' if lo > 0 or hi < 0 else ''
    return f"{m:+.4f} [{lo:+.4f}, {hi:+.4f}]{star}"


def plan(r):
    return ' '.join(f"{o['name']}({o['g']},{o['p']})" for o in r['objects'])


base = rows(sys.argv[1])
area = {}
for p in sys.argv[2:]:
    area.update(rows(p))
scenes = sorted({k[0] for k in area})
print('## Plans and scene quality, paper objective (mean) vs area objective\n')
print('| scene | device | selector | objective | plan | MB | SSIM | PSNR | LPIPS | area − mean SSIM [95 % CI] |')
print('|---|---|---|---|---|---|---|---|---|---|')
for s in scenes:
    for dev in ('iphone13', 'pixel4'):
        for m in ('dp', 'slsqp'):
            b, a = base.get((s, dev, m)), area.get((s, dev, m))
            if not (b and a and b['quality'] and a['quality']):
                continue
            for name, r in (('mean', b), ('area', a)):
                q = r['quality']
                d = fmt(*paired(a, b)) if name == 'area' else ''
                same = ' (same plan)' if name == 'area' and plan(a) == plan(b) else ''
                print(f"| {s} | {dev} | {m} | {name} | {plan(r)}{same} | {r['file_bytes'] / 1e6:.1f} | "
                      f"{q['ssim']:.4f} | {q['psnr']:.2f} | {q['lpips']:.4f} | {d} |")
print('\n## The paper\'s claims under the area objective (SSIM, DP − other [95 % CI]; * excludes 0)\n')
print('| scene | device | DP − Fairness | DP − SLSQP | DP − Block | DP − Single | (paper objective: DP − Fairness, DP − SLSQP) |')
print('|---|---|---|---|---|---|---|')
for s in scenes:
    for dev in ('iphone13', 'pixel4'):
        dp = area.get((s, dev, 'dp'))
        if not (dp and dp['quality']):
            continue
        cells = []
        for m in ('fairness', 'slsqp', 'block', 'single'):
            o = area.get((s, dev, m))
            cells.append(fmt(*paired(dp, o)) if o and o['quality'] else 'n/a')
        bdp = base.get((s, dev, 'dp'))
        old = []
        for m in ('fairness', 'slsqp'):
            o = base.get((s, dev, m))
            old.append(fmt(*paired(bdp, o)) if bdp and o and o['quality'] else 'n/a')
        print(f"| {s} | {dev} | " + ' | '.join(cells) + ' | ' + '; '.join(old) + ' |')
