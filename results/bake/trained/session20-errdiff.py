# Session 20 (docs/baking.md, "Session 20"): where bake B's held-out SSIM is lower
# than bake A's, split into the silhouette band (3 px either side), the object's
# interior and the background; per view also the squared error of each region.
# DIR_A and DIR_B hold `nerflex bake --measure --renders DIR` output (test_i.png,
# truth_i.png). Needs numpy, Pillow and scipy (pip install scipy).
# usage: session20-errdiff.py DIR_A DIR_B [nviews] [diff.png]
import sys, numpy as np
from PIL import Image
from scipy.ndimage import gaussian_filter, binary_erosion, binary_dilation
A, B = sys.argv[1], sys.argv[2]; n = int(sys.argv[3]) if len(sys.argv) > 3 else 10
def load(p): return np.asarray(Image.open(p).convert('RGB'), dtype=np.float64) / 255.0
def ssim_map(x, y):
    C1, C2 = 0.01**2, 0.03**2
    f = lambda z: gaussian_filter(z, 1.5, truncate=3.5)
    m = []
    for c in range(3):
        a, b = x[..., c], y[..., c]
        mu_a, mu_b = f(a), f(b)
        saa = f(a*a) - mu_a**2; sbb = f(b*b) - mu_b**2; sab = f(a*b) - mu_a*mu_b
        m.append(((2*mu_a*mu_b + C1) * (2*sab + C2)) / ((mu_a**2 + mu_b**2 + C1) * (saa + sbb + C2)))
    return np.mean(m, axis=0)
tot = {}
for i in range(n):
    t = load(f'{A}/truth_{i}.png'); a = load(f'{A}/test_{i}.png'); b = load(f'{B}/test_{i}.png')
    sa, sb = ssim_map(a, t), ssim_map(b, t)
    obj = (t.min(axis=2) < 0.99)
    edge = binary_dilation(obj, iterations=3) & ~binary_erosion(obj, iterations=3)
    inner = obj & ~edge
    bg = ~obj & ~edge
    rendered_b = b.min(axis=2) < 0.99; rendered_a = a.min(axis=2) < 0.99
    N = t.shape[0] * t.shape[1]
    d = (sb - sa)
    row = {}
    for name, m in [('edge', edge), ('inner', inner), ('bg', bg)]:
        row[name] = d[m].sum() / N
        tot[name] = tot.get(name, 0) + row[name] / n
    ea = ((a - t)**2).mean(axis=2); eb = ((b - t)**2).mean(axis=2)
    print(f'view {i}: dSSIM {d.mean():+.4f} edge {row["edge"]:+.4f} inner {row["inner"]:+.4f} bg {row["bg"]:+.4f} | mse a {ea.mean():.5f} b {eb.mean():.5f}; inner mse a {ea[inner].mean():.5f} b {eb[inner].mean():.5f} edge a {ea[edge].mean():.5f} b {eb[edge].mean():.5f}; px b-only {int((rendered_b & ~rendered_a).sum())} a-only {int((rendered_a & ~rendered_b).sum())}')
    if i == 0:  # view 0's SSIM difference: red where B is worse, green where better
        Image.fromarray((np.stack([np.clip(-d*10,0,1), np.clip(d*10,0,1), np.zeros_like(d)], -1) * 255).astype(np.uint8)).save(sys.argv[4] if len(sys.argv) > 4 else '/tmp/diff0.png')
print('mean', {k: round(v, 5) for k, v in tot.items()})
