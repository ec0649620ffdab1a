#!/usr/bin/env python3
"""Held-out SSIM / PSNR / LPIPS of one scene in two `nerflex eval` reports, side by side.

usage: compare.py OLD/report.md NEW/report.md SCENE
Reads each report's "### SCENE" table of means (the first table under the
heading) and prints a markdown table: method, device, old → new.
"""
import sys


def means(path, scene):
    rows, inside, table = {}, False, False
    for line in open(path, encoding="utf-8"):
        s = line.strip()
        if s.startswith("### "):
            inside = s == "### " + scene
            table = False
            continue
        if not inside:
            continue
        if s.startswith("| device | method | SSIM"):
            table = True
            continue
        if table and s.startswith("|---"):
            continue
        if table and s.startswith("|"):
            c = [x.strip() for x in s.strip("|").split("|")]
            rows[(c[1], c[0])] = (float(c[2]), float(c[3]), float(c[4]), c[6])
            continue
        if table:
            break
    if not rows:
        sys.exit(f"error: no '### {scene}' table of means in {path}")
    return rows


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    old, new = means(sys.argv[1], sys.argv[3]), means(sys.argv[2], sys.argv[3])
    print("| method | device | SSIM old → new | PSNR dB old → new | LPIPS old → new | baked MB old → new |")
    print("|---|---|---|---|---|---|")
    for key in new:
        if key not in old:
            continue
        o, n = old[key], new[key]
        print(f"| {key[0]} | {key[1]} | {o[0]:.4f} → {n[0]:.4f} ({n[0]-o[0]:+.4f}) | "
              f"{o[1]:.2f} → {n[1]:.2f} | {o[2]:.4f} → {n[2]:.4f} | {o[3]} → {n[3]} |")


if __name__ == "__main__":
    main()
