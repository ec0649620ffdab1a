#!/usr/bin/env python3
"""One line per sweep CSV of `nerflex bake --sweep --csv` (session 34):
object, the best held-out SSIM and where, the corners (32, 5) and
(256, 17), the dynamic range between them, and the neighbouring pairs
(next g or next p) whose SSIM falls by more than 0.002 (count, largest).
`table.py` prints one sweep's whole grid.
Usage: results/bake/trained/builtin/summary.py A.csv [B.csv …]
"""
import sys

from table import falls, read


def main(paths):
    print("| sweep | object | best SSIM / PSNR at (g, p) | (32, 5) | (256, 17) | range SSIM / dB | falls > 0.002 (largest) |")
    print("|---|---|---|---|---|---|---|")
    for path in paths:
        rows = read(path)
        if not rows:
            print(f"| {path} | (empty) | | | | | |")
            continue
        obj = next(iter(rows.values()))["object"]
        best_key = max(rows, key=lambda k: float(rows[k]["ssim"]))
        best = rows[best_key]
        lo, hi = rows.get((32, 5)), rows.get((256, 17))

        def cell(r):
            return f"{float(r['ssim']):.4f} / {float(r['psnr']):.2f}" if r else "–"

        rng = (
            f"{float(hi['ssim']) - float(lo['ssim']):+.4f} / {float(hi['psnr']) - float(lo['psnr']):+.2f}"
            if lo and hi
            else "–"
        )
        fl = falls(rows)
        fall_text = f"{len(fl)}" + (
            f" ({fl[0][0]:+.4f}, {fl[0][1]} → {fl[0][2]})" if fl else ""
        )
        name = path.rsplit("/", 1)[-1]
        print(
            f"| {name} | {obj} | {cell(best)} at {best_key} | {cell(lo)} | {cell(hi)} | {rng} | {fall_text} |"
        )


if __name__ == "__main__":
    main(sys.argv[1:])
