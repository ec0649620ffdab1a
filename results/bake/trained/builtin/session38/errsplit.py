# Squared error of two renders against a photo by region: background (photo near white), edge (within 3 px of it), interior; and how heavy-tailed the interior error is. Usage: errsplit.py PHOTO.png A.png B.png
import os, sys; sys.path.insert(0, os.path.dirname(os.path.abspath(__file__))); import png_rgb as png
ref=png.read(sys.argv[1]); a=png.read(sys.argv[2]); b=png.read(sys.argv[3])
H=len(ref); W=len(ref[0])
# background = near-white in ref
bg=[[all(c>=250 for c in ref[y][x]) for x in range(W)] for y in range(H)]
def near_bg(y,x,r=3):
    for yy in range(max(0,y-r),min(H,y+r+1)):
        for xx in range(max(0,x-r),min(W,x+r+1)):
            if bg[yy][xx]: return True
    return False
cats={'edge':[0,0,0],'interior':[0,0,0],'bg':[0,0,0]}
big={'a':0,'b':0}; tailA=0; tailB=0
ea_list=[];eb_list=[]
for y in range(H):
    for x in range(W):
        ea=sum((a[y][x][k]-ref[y][x][k])**2 for k in range(3)); eb=sum((b[y][x][k]-ref[y][x][k])**2 for k in range(3))
        c='bg' if bg[y][x] else ('edge' if near_bg(y,x) else 'interior')
        cats[c][0]+=ea; cats[c][1]+=eb; cats[c][2]+=1
        if c=='interior': ea_list.append(ea); eb_list.append(eb)
for c,v in cats.items(): print(c, 'px',v[2],'A %.2fM B %.2fM'%(v[0]/1e6,v[1]/1e6))
for name,l in (('A',ea_list),('B',eb_list)):
    l=sorted(l,reverse=True); tot=sum(l)
    print(name,'interior: top 0.1%% px %.1f%%, top 1%% %.1f%%, top 10%% %.1f%%' % tuple(100*sum(l[:int(len(l)*f)])/tot for f in (0.001,0.01,0.1)))
    print(name, 'interior error excluding top 1%%: %.2fM' % (sum(l[int(len(l)*0.01):])/1e6))
