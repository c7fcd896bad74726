#!/usr/bin/env python3
"""trajectory.txt and map.ply of a replay against the ground truth expressed as the base in the map frame.

    frame_check.py RECORDING REPLAY_OUT     (python3-numpy)
"""
import sys, struct, numpy as np, re
rec, out = sys.argv[1], sys.argv[2]
def quat(x,y,z,w):
    n=np.sqrt(x*x+y*y+z*z+w*w); x,y,z,w=x/n,y/n,z/n,w/n
    return np.array([[1-2*(y*y+z*z),2*(x*y-z*w),2*(x*z+y*w)],[2*(x*y+z*w),1-2*(x*x+z*z),2*(y*z-x*w)],[2*(x*z-y*w),2*(y*z+x*w),1-2*(x*x+y*y)]])
def T(t,q):
    M=np.eye(4); M[:3,:3]=quat(*q); M[:3,3]=t; return M
def load(p):
    d={}
    for l in open(p):
        if l.startswith('#') or not l.strip(): continue
        v=[float(a) for a in l.replace(',',' ').split()]
        d[round(v[0],4)]=T(v[1:4],v[4:8])
    return d
cal=open(rec+'/calibration.yaml').read()
m=re.search(r'T_base_cam:.*?\n\s*translation: \[([^\]]*)\]\s*\n\s*rotation_xyzw: \[([^\]]*)\]',cal,re.S)
Tbc=T([float(a) for a in m.group(1).split(',')],[float(a) for a in m.group(2).split(',')])
gt=load(rec+'/groundtruth.txt'); est=load(out+'/trajectory.txt')
first=sorted(gt)[0]; inv0=np.linalg.inv(gt[first]); Tcb=np.linalg.inv(Tbc)
errs=[];zs=[]
for s,E in est.items():
    if s not in gt: continue
    G=Tbc@inv0@gt[s]@Tcb
    errs.append(np.linalg.norm(G[:3,3]-E[:3,3])); zs.append(E[2,3])
errs=np.array(errs); zs=np.array(zs)
print(f"poses {len(errs)}: unaligned position error vs base-frame ground truth median {np.median(errs):.4f} max {errs.max():.4f} m; base height |z| max {np.abs(zs).max():.4f} m")
b=open(out+'/map.ply','rb').read(); h=b.index(b'end_header\n')+11; n=int(re.search(rb'element vertex (\d+)',b).group(1))
pts=np.frombuffer(b[h:h+n*15],dtype=np.dtype([('x','<f4'),('y','<f4'),('z','<f4'),('r','u1'),('g','u1'),('b','u1')]))
z=pts['z']
print(f"map {n} points: |z|<0.03 m {np.mean(np.abs(z)<0.03)*100:.1f} %, z<-0.05 m {np.mean(z<-0.05)*100:.2f} %, z range {z.min():.2f}..{z.max():.2f} m")
