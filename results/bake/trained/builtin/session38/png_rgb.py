# A minimal PNG reader (8-bit grey/RGB/RGBA, composited over white) and RGB writer, pure Python: no imaging library on this machine (session 38).
import zlib, struct
def read(path):
    d=open(path,'rb').read(); assert d[:8]==b'\x89PNG\r\n\x1a\n'
    i=8; idat=b''; 
    while i<len(d):
        n=struct.unpack('>I',d[i:i+4])[0]; t=d[i+4:i+8]; c=d[i+8:i+8+n]; i+=12+n
        if t==b'IHDR': w,h,bd,ct=struct.unpack('>IIBB',c[:10])
        elif t==b'IDAT': idat+=c
    assert bd==8
    ch={2:3,6:4,0:1,4:2}[ct]; raw=zlib.decompress(idat); st=w*ch
    out=bytearray(h*st); prev=bytearray(st); p=0
    for y in range(h):
        f=raw[p]; line=bytearray(raw[p+1:p+1+st]); p+=1+st
        if f==1:
            for x in range(ch,st): line[x]=(line[x]+line[x-ch])&255
        elif f==2:
            for x in range(st): line[x]=(line[x]+prev[x])&255
        elif f==3:
            for x in range(st): line[x]=(line[x]+((line[x-ch] if x>=ch else 0)+prev[x])//2)&255
        elif f==4:
            for x in range(st):
                a=line[x-ch] if x>=ch else 0; b=prev[x]; c=prev[x-ch] if x>=ch else 0
                pa=abs(b-c); pb=abs(a-c); pc=abs(a+b-2*c)
                pr=a if pa<=pb and pa<=pc else (b if pb<=pc else c)
                line[x]=(line[x]+pr)&255
        out[y*st:(y+1)*st]=line; prev=line
    # to RGB over white
    rgb=[]
    for y in range(h):
        row=[]
        for x in range(w):
            q=(y*w+x)*ch
            if ch==4:
                a=out[q+3]/255; row.append(tuple(int(round(out[q+k]*a+255*(1-a))) for k in range(3)))
            elif ch==3: row.append(tuple(out[q:q+3]))
            else: row.append((out[q],)*3)
        rgb.append(row)
    return rgb
def write(path, img):
    h=len(img); w=len(img[0])
    raw=b''.join(b'\x00'+bytes(v for px in row for v in px) for row in img)
    def chunk(t,c): return struct.pack('>I',len(c))+t+c+struct.pack('>I',zlib.crc32(t+c)&0xffffffff)
    open(path,'wb').write(b'\x89PNG\r\n\x1a\n'+chunk(b'IHDR',struct.pack('>IIBBBBB',w,h,8,2,0,0,0))+chunk(b'IDAT',zlib.compress(raw,6))+chunk(b'IEND',b''))
