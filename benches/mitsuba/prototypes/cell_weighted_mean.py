#!/usr/bin/env python3
"""The mean of a plan's samples weighted by cells inside each pixel (issue 38, texture rows): per pixel the
occupied 2^l x 2^l sub-cells' means averaged with equal weights, beside the plain mean, on a `suite.py plan
--workdir WD` run's samples (whether a deepened pixel's samples are balanced over its children).

    PY=/work/venv-mitsuba/bin/python
    $PY benches/mitsuba/prototypes/cell_weighted_mean.py WD stripes,grid 4,8,16
"""
import sys, os, numpy as np
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..'))
import oidn, metrics
n=128; wd=sys.argv[1]
def strat_mean(s, n, levels):
    # per pixel: mean over the occupied 2^l x 2^l sub-cells of the cells' means (area weights, renormalised over occupied cells)
    x,y=s[:,0],s[:,1]
    px=np.clip(np.floor(x).astype(int),0,n-1); py=np.clip(np.floor(y).astype(int),0,n-1)
    k=1<<levels
    sx=np.clip(np.floor((x-px)*k).astype(int),0,k-1); sy=np.clip(np.floor((y-py)*k).astype(int),0,k-1)
    cell=((py*n+px)*k+sy)*k+sx
    N=n*n*k*k
    cnt=np.bincount(cell,minlength=N)
    out=np.zeros((n*n,3))
    occ=(cnt>0).reshape(n*n,k*k)
    for c in range(3):
        m=np.bincount(cell,weights=s[:,2+c],minlength=N)/np.maximum(cnt,1)
        m=m.reshape(n*n,k*k)
        out[:,c]=(m*occ).sum(1)/np.maximum(occ.sum(1),1)
    return out.reshape(n,n,3)
for scene in sys.argv[2].split(','):
  for spp in [int(p) for p in sys.argv[3].split(',')]:
    ref=np.load(f'/work/suite-cache/{scene}/ref.npy')
    s=np.load(os.path.join(wd,f'{scene}-{n}x{n}-{spp}-all.npy'))
    pm=oidn.pixel_mean(s,n,n)[0]
    r=[f'plain {metrics.psnr(pm,ref):.2f} ({metrics.relmse(pm,ref):.3g})']
    for l in (1,2):
        sm=strat_mean(s,n,l); r.append(f'strata {1<<l}x{1<<l} {metrics.psnr(sm,ref):.2f} ({metrics.relmse(sm,ref):.3g})')
    u=oidn.pixel_mean(np.load(f'/work/suite-cache/{scene}/samples-{spp}.npy'),n,n)[0]
    print(scene,spp,' | '.join(r), f'| uniform box {metrics.psnr(u,ref):.2f}')
