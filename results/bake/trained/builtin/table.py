#!/usr/bin/env python3
"""Summarises sweep CSVs of `nerflex bake --sweep --csv` (session 27):
per CSV, held-out SSIM / PSNR / file MB over the (g, p) grid, the
dynamic range (256, 17) against (32, 5), and every neighbouring pair
(next g or next p) whose SSIM falls by more than 0.002.
Usage: results/bake/trained/builtin/table.py A.csv [B.csv …]
"""
import csv
import sys


def read(path):
    """A sweep CSV as {(g, p): row}."""
    rows = {}
    with open(path) as f:
        for r in csv.DictReader(f):
            rows[(int(r["g"]), int(r["p"]))] = r
    return rows


def falls(rows, by=0.002):
    """Neighbouring pairs (next g or next p) whose SSIM falls by more than
    `by`, largest first: (change, (g, p), next)."""
    gs = sorted({g for g, _ in rows})
    ps = sorted({p for _, p in rows})
    out = []
    for (g, p), r in rows.items():
        nexts = []
        if gs.index(g) + 1 < len(gs):
            nexts.append((gs[gs.index(g) + 1], p))
        if ps.index(p) + 1 < len(ps):
            nexts.append((g, ps[ps.index(p) + 1]))
        for n in nexts:
            if n in rows:
                d = float(rows[n]["ssim"]) - float(r["ssim"])
                if d < -by:
                    out.append((d, (g, p), n))
    return sorted(out)


def main(paths):
    for path in paths:
        rows = read(path)
        gs = sorted({g for g, _ in rows})
        ps = sorted({p for _, p in rows})
        print(f"## {path}\n")
        print("| p \\ g | " + " | ".join(str(g) for g in gs) + " |")
        print("|---" * (len(gs) + 1) + "|")
        for p in ps:
            cells = []
            for g in gs:
                r = rows.get((g, p))
                cells.append(
                    f"{float(r['ssim']):.4f} / {float(r['psnr']):.2f} / {int(r['size_bytes']) / 1e6:.1f}"
                    if r else ""
                )
            print(f"| {p} | " + " | ".join(cells) + " |")
        hi, lo = rows.get((256, 17)), rows.get((32, 5))
        if hi and lo:
            print(
                f"\nrange (256, 17) − (32, 5): {float(hi['ssim']) - float(lo['ssim']):+.4f} SSIM, "
                f"{float(hi['psnr']) - float(lo['psnr']):+.2f} dB"
            )
        fl = sorted(f"({g}, {p}) → {n}: {d:+.4f}" for d, (g, p), n in falls(rows))
        print(f"falls over 0.002: {len(fl)}" + ("" if not fl else ": " + "; ".join(fl)))
        print()


if __name__ == "__main__":
    main(sys.argv[1:])
