#!/usr/bin/env python3
"""Share of near-white background pixels (every channel >= 250, over white) in
each network's held-out views (session 40).

usage: background.py SEGMENT_DIR [VIEWS]   (an eval work folder's scenes/<scene>/segment)
Reads the first VIEWS (default 3) test images r_N.png of every group folder."""
import os, sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '../../bake/trained/builtin/session38'))
import png_rgb as png

seg = sys.argv[1]
views = int(sys.argv[2]) if len(sys.argv) > 2 else 3
print('| network | views | near-white share |')
print('|---|---|---|')
for net in sorted(d for d in os.listdir(seg) if os.path.isdir(os.path.join(seg, d, 'test'))):
    tot = bg = 0
    for v in range(views):
        for row in png.read(os.path.join(seg, net, 'test', f'r_{v}.png')):
            for px in row:
                tot += 1
                bg += all(c >= 250 for c in px)
    print(f'| {net} | {views} | {100 * bg / tot:.1f} % |')
