#!/usr/bin/env python3
"""Where a bake's held-out error above its field's lies (session 23).

usage: session23-gap.py FIELD_RENDERS BAKE_RENDERS
  FIELD_RENDERS: `nerflex train --capture C --field F --measure --renders DIR`
  BAKE_RENDERS:  `nerflex bake … --measure --renders DIR` (has truth_i.png)

Prints the squared error of both by pixel class (background, a 5-pixel
silhouette band, bake holes, interior edges, interior flat) and by
outliers (pixels off by more than 0.1 in the mean of |RGB| error, in the
bake only, in the field only, in both, in neither), each with its share
of the difference between the two.
"""
import glob
import os
import sys

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view as sw
from PIL import Image


def load(p):
    return np.asarray(Image.open(p).convert('RGB'), np.float64) / 255


def psnr(se, n):
    return 10 * np.log10(n / max(se, 1e-12))


def main(field_dir, bake_dir):
    cls, out, n = {}, {}, 0
    for t in sorted(glob.glob(os.path.join(bake_dir, 'truth_*.png'))):
        i = t.rsplit('_', 1)[1].split('.')[0]
        gt, b, f = load(t), load(f'{bake_dir}/test_{i}.png'), load(f'{field_dir}/test_{i}.png')
        n += gt.shape[0] * gt.shape[1]
        seb, sef = ((b - gt) ** 2).mean(2), ((f - gt) ** 2).mean(2)
        g = gt.mean(2)
        grad = np.maximum(np.abs(np.diff(g, axis=1, append=g[:, -1:])),
                          np.abs(np.diff(g, axis=0, append=g[-1:, :])))
        white = gt.min(2) > 0.99
        win = sw(np.pad(white, 2, mode='edge'), (5, 5))
        band = win.any((2, 3)) & (~win).any((2, 3))
        hole = ~white & ~band & (b.min(2) > 0.99)
        inner = ~white & ~band & ~hole
        masks = {
            'background': white & ~band,
            'silhouette band (5 px)': band,
            'hole (bake white, truth not)': hole,
            'interior edge (gradient > 0.1)': inner & (grad > 0.1),
            'interior flat': inner & (grad <= 0.1),
        }
        eb, ef = np.abs(b - gt).mean(2) > 0.1, np.abs(f - gt).mean(2) > 0.1
        outl = {
            'off > 0.1 in both': eb & ef,
            'off > 0.1 in the bake only': eb & ~ef,
            'off > 0.1 in the field only': ~eb & ef,
            'off > 0.1 in neither': ~eb & ~ef,
        }
        for acc, ms in ((cls, masks), (out, outl)):
            for k, m in ms.items():
                a = acc.setdefault(k, [0, 0.0, 0.0])
                a[0] += m.sum()
                a[1] += sef[m].sum()
                a[2] += seb[m].sum()
    tf = sum(a[1] for a in cls.values())
    tb = sum(a[2] for a in cls.values())
    print(f'pooled over {n} pixels: field {psnr(tf, n):.2f} dB, bake {psnr(tb, n):.2f} dB')
    for title, acc in (('by class', cls), ('by outliers', out)):
        print(f'\n{title:32s} {"px %":>6s} {"field dB":>8s} {"bake dB":>8s} {"share of the gap %":>18s}')
        for k, (c, ef, eb) in acc.items():
            print(f'{k:32s} {100 * c / n:6.2f} {psnr(ef, c):8.2f} {psnr(eb, c):8.2f} '
                  f'{100 * (eb - ef) / (tb - tf):18.1f}')


if __name__ == '__main__':
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
