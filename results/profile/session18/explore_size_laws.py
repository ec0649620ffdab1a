#!/usr/bin/env python3
"""Session 18: candidate size laws on a bake sweep, fitted in f64 (numpy).

Each law is linear in its non-negative coefficients for fixed nonlinear
parameters (a, b and any free power), so the coefficients come from
non-negative least squares on relative residuals (variable projection) and
the nonlinear ones from a coarse grid plus coordinate search, inside the
bounds the Rust fitter uses (a in [-g_min/2, 2 g_max], b in [-p_min/2,
max(256 - 2 p_max, 2 p_max)], powers in [1, 4]). This is an exploration
tool, not the profiler: the figures in docs/profiler.md's tables come from
`nerflex profile accuracy` (fixed point, bounded LM), which agrees with
this script on the laws both implement (surface, quads) to the printed
digits on the trained planes and within 0.6 percentage points on the mesh.

Outputs: explore_planes.txt (results/bake/trained/samples.csv, every law
below; `sat` run separately and appended), explore_mesh.txt
(samples-mesh.csv: surface, power, quad2, 1.5:2).

Laws (G = g + a, P = p + b; coefficients k, c, m >= 0):
  surface    k G^2 P^2 + m                (the paper's form with e = 2)
  volume     k G^3 P^2 + m                (the paper's form)
  power      k G^e P^2 + m                e fitted
  quad2      k G^2 P^2 + c G^2 + m        a per-quad constant, e = 2
  power+c    k G^e P^2 + c G^2 + m        e fitted
  e:f        k G^e P^2 + c G^f + m        fixed e, f (quads = 1.5:2)
  sat        (k G^1.5 P^2 + c G^2)/(1 + G/h) + m   h in [16, 65536] fitted

Usage: explore_size_laws.py SAMPLES.csv law[,law…]
Prints, per law, leave-one-out and variable-step (g {16, 64, 256} x p {5, 9, 17}
on the trained sweeps) errors: mean ± sd of |error| in MB and %, and the
worst under-prediction (most negative (predicted - measured)/measured).
"""
import csv
import itertools
import sys

import numpy as np


def load(path):
    d = {}
    for r in csv.DictReader(open(path)):
        d.setdefault(r["object"], []).append((int(r["g"]), int(r["p"]), float(r["size_bytes"])))
    return {k: np.array(v) for k, v in d.items()}


def free_powers(law):
    """Nonlinear parameters beyond a, b (each searched in [1, 4])."""
    return {"power": 1, "power+c": 1, "sat": 1}.get(law, 0)


def basis(law, th, g, p):
    G, P = g + th[0], p + th[1]
    one = np.ones_like(G)
    if law == "surface":
        return np.stack([G**2 * P**2, one], 1)
    if law == "volume":
        return np.stack([G**3 * P**2, one], 1)
    if law == "power":
        return np.stack([G ** th[2] * P**2, one], 1)
    if law == "quad2":
        return np.stack([G**2 * P**2, G**2, one], 1)
    if law == "sat":
        # quads over a saturation 1 + G/h, h = 2^(4 t) for t in [1, 4].
        d = 1 + G / 2.0 ** (4 * th[2])
        return np.stack([G**1.5 * P**2 / d, G**2 / d, one], 1)
    if law == "power+c":
        return np.stack([G ** th[2] * P**2, G**2, one], 1)
    e, f = (float(x) for x in law.split(":"))
    return np.stack([G**e * P**2, G**f, one], 1)


def nnls(A, y):
    """Non-negative least squares by trying every active set (<= 3 columns)."""
    best = None
    for mask in itertools.product([0, 1], repeat=A.shape[1]):
        idx = [i for i, on in enumerate(mask) if on]
        x = np.zeros(A.shape[1])
        if idx:
            sol, *_ = np.linalg.lstsq(A[:, idx], y, rcond=None)
            if (sol < 0).any():
                continue
            x[idx] = sol
        r = float(np.sum((A @ x - y) ** 2))
        if best is None or r < best[0]:
            best = (r, x)
    return best


def fit(law, g, p, s, dom):
    gmin, gmax, pmin, pmax = dom
    lo = [-gmin / 2, -pmin / 2] + [1.0] * free_powers(law)
    hi = [2 * gmax, max(256 - 2 * pmax, 2 * pmax)] + [4.0] * free_powers(law)

    def obj(th):
        th = np.clip(th, lo, hi)
        return nnls(basis(law, th, g, p) / s[:, None], np.ones_like(s))

    a0 = np.concatenate([np.linspace(lo[0], 0, 4), np.linspace(0, hi[0], 7)[1:]])
    b0 = np.concatenate([np.linspace(lo[1], 0, 3), [1, 2, 4, 8, 16, 32, 64, 128, hi[1]]])
    e0 = list(itertools.product([1.5, 2, 2.5, 3], repeat=free_powers(law)))
    starts = sorted(
        ((obj(np.array([a, b, *e]))[0], [a, b, *e]) for a in a0 for b in b0 for e in e0),
        key=lambda t: t[0],
    )
    best = None
    for r, th in starts[:3]:
        th = np.array(th, float)
        step = np.array([(h - l) / 20 for l, h in zip(lo, hi)])
        while step.max() > 1e-7:
            improved = False
            for i in range(len(th)):
                for sgn in (1, -1):
                    t2 = th.copy()
                    t2[i] = np.clip(t2[i] + sgn * step[i], lo[i], hi[i])
                    r2 = obj(t2)[0]
                    if r2 < r:
                        th, r, improved = t2, r2, True
            if not improved:
                step /= 2
        if best is None or r < best[0]:
            best = (r, th)
    th = best[1]
    return th, obj(th)[1]


def variable_step(values, factor=3):
    out = [values[0]]
    while True:
        nxt = [v for v in values if v >= factor * out[-1]]
        if not nxt:
            return out
        out.append(nxt[0])


def evaluate(law, data):
    loo, vs = [], []
    for name, arr in data.items():
        g, p, s = arr[:, 0], arr[:, 1], arr[:, 2]
        dom = (g.min(), g.max(), p.min(), p.max())
        for i in range(len(s)):
            keep = np.arange(len(s)) != i
            th, x = fit(law, g[keep], p[keep], s[keep], dom)
            loo.append((name, g[i], p[i], s[i], (basis(law, th, g[i : i + 1], p[i : i + 1]) @ x)[0]))
        gs, ps = sorted(set(g)), sorted(set(p))
        mid = (ps[0] + ps[-1]) / 2
        tp = {ps[0], min(ps, key=lambda v: (abs(v - mid), v)), ps[-1]}
        tg = set(variable_step(gs))
        train = np.array([gi in tg and pi in tp for gi, pi in zip(g, p)])
        th, x = fit(law, g[train], p[train], s[train], dom)
        pred = basis(law, th, g[~train], p[~train]) @ x
        vs += [(name, *t) for t in zip(g[~train], p[~train], s[~train], pred)]
    return loo, vs


def summary(rows):
    s = np.array([r[3] for r in rows])
    pr = np.array([r[4] for r in rows])
    mb = np.abs(pr - s) / 1e6
    rel = (pr - s) / s * 100
    w = int(np.argmin(rel))
    return (
        f"n {len(s):3d}  MB {mb.mean():6.2f} ± {mb.std():6.2f}  % {np.abs(rel).mean():5.2f} ± {np.abs(rel).std():5.2f}"
        f"  worst under {rel[w]:+6.1f} % ({rows[w][0]} {rows[w][1]:.0f}/{rows[w][2]:.0f})"
    )


if __name__ == "__main__":
    data = load(sys.argv[1])
    for law in sys.argv[2].split(","):
        loo, vs = evaluate(law, data)
        print(f"{law:9s} leave-one-out  {summary(loo)}")
        print(f"{law:9s} variable-step  {summary(vs)}", flush=True)
