#!/usr/bin/env python3
"""Headroom of per-pixel allocation for the box mean (texture rows). Per-pixel clipped squared error of
Mitsuba's box film at n in {4, 8, 16, 35} modelled as c_P n^-a (a from the totals' log-log slope).
Allocation from c_P estimated on films {4, 8, 35}; evaluated with c_P from film 16 alone (independent
render): E(n_P) = mean_P c16_P (n_P)^-a where c16_P = e16_P 16^a. Rule: n_P = max(m, lambda c_P^(1/(1+a)))
with mean n_P = N (m the floor). A model bound, not a measurement of any sampler: c_P comes from 47 samples
a pixel the plan never has (prototypes/pixel_allocation.py measures what a plan's own samples can do).

    PY=/work/venv-mitsuba/bin/python
    $PY benches/mitsuba/prototypes/allocation_headroom.py stripes,grid,direct,thinlens,text,grazing
"""
import sys
import numpy as np
def alloc(w, N, m):
    lo, hi = 0.0, 1e12
    for _ in range(200):
        lam=(lo+hi)/2; n=np.maximum(m, lam*w)
        lo,hi=(lam,hi) if n.mean()<N else (lo,lam)
    return np.maximum(m, lo*w)
for sc in sys.argv[1].split(','):
    ref=np.load(f'/work/suite-cache/{sc}/ref.npy'); clip=np.clip(ref,0,1)
    ns=[4,8,16,35]
    e={n: ((np.clip(np.load(f'/work/suite-cache/{sc}/film-box-{32 if n==35 else n}.npy').astype(float),0,1)-clip)**2).mean(2).ravel() for n in ns}
    tot={n:e[n].mean() for n in ns}
    a=-np.polyfit(np.log(ns),np.log([tot[n] for n in ns]),1)[0]
    c=np.mean([e[n]*n**a for n in (4,8,35)],axis=0)
    ce=e[16]*16**a
    out=[f'{sc}: a={a:.2f}']
    for N in (4,8,16):
        uni=(ce*N**-a).mean()
        r=[f'N={N}: uniform {10*np.log10(1/uni):.2f}']
        for m in (1, N/2):
            for name,g in (('jensen',1/(1+a)),('neyman',0.5)):
                nP=alloc(c**g,N,m); E=(ce*nP**-a).mean()
                r.append(f'{name} floor {m:g} {10*np.log10(uni/E):+.2f}')
        out.append(', '.join(r))
    print('\n  '.join(out))
