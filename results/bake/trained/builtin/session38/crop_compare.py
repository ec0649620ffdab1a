# Side-by-side crops (x0 y0 w h, scaled) of a photo and renders, then each render's |error| × 4 against the photo. Usage: crop_compare.py OUT.png X0 Y0 W H SCALE PHOTO.png A.png [B.png …]
import os, sys; sys.path.insert(0, os.path.dirname(os.path.abspath(__file__))); import png_rgb as png
# usage: cmp.py out.png x0 y0 w h scale img1 img2 ...  ; also error maps vs first
out,x0,y0,w,h,s=sys.argv[1],*map(int,sys.argv[2:7]); ims=[png.read(p) for p in sys.argv[7:]]
ref=ims[0]
tiles=[]
for im in ims:
    tiles.append([[im[y][x] for x in range(x0,x0+w)] for y in range(y0,y0+h)])
for im in ims[1:]:
    tiles.append([[tuple([min(255,4*abs(im[y][x][k]-ref[y][x][k])) for k in range(3)].__iter__()) for x in range(x0,x0+w)] for y in range(y0,y0+h)])
rows=[]
for y in range(h*s):
    row=[]
    for t in tiles:
        row+= [t[y//s][x//s] for x in range(w*s)] + [(255,0,0)]*2
    rows.append(row)
png.write(out,rows)
# errors
for p,im in zip(sys.argv[8:],ims[1:]):
    se=sum((im[y][x][k]-ref[y][x][k])**2 for y in range(len(ref)) for x in range(len(ref[0])) for k in range(3))
    print(p, 'sum sq err/1e6', se/1e6)
