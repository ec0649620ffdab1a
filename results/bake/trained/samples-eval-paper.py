#!/usr/bin/env python3
"""Writes results/bake/trained/samples-eval-paper.csv from results/eval/eval.json:
the paper-scale evaluation's profiler samples (every scene's, then the real
composite's), one row per sample bake, objects named SCENE.OBJECT (the real
composite is `real`), in the CSV layout of `nerflex bake --sweep --csv`.
Usage: results/bake/trained/samples-eval-paper.py [eval.json] > results/bake/trained/samples-eval-paper.csv
"""
import json
import sys

path = sys.argv[1] if len(sys.argv) > 1 else "results/eval/eval.json"
with open(path) as f:
    report = json.load(f)
print("object,g,p,size_bytes,gpu_bytes,quads,ssim,psnr,lpips")
scenes = [(s["scene"], s) for s in report["scenes"]]
if report.get("real"):
    scenes.append(("real", report["real"]))
for label, scene in scenes:
    for s in scene["samples"]:
        print(
            f"{label}.{s['object']},{s['g']},{s['p']},{s['size_bytes']},{s['gpu_bytes']},"
            f"{s['quads']},{s['ssim']:.6f},{s['psnr']:.4f},{s['lpips']:.6f}"
        )
