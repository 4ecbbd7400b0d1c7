# Issue 11 round-off probe: writes /tmp/ro/*.bin (samples, long double truth hi+lo parts).
import numpy as np
def ld(x):
    X = x.astype(np.longdouble); return np.sin(20*X)+np.exp(X)
def hl(v):
    hi = v.astype(np.float64); lo = (v - hi.astype(np.longdouble)).astype(np.float64); return hi, lo
for m in [10**5, 10**6]:
    x = np.sort(np.random.default_rng(0).uniform(0,1,m))
    y64 = np.sin(20*x)+np.exp(x)
    hi, lo = hl(ld(x))
    for n,a in [("x",x),("y64",y64),("yhi",hi),("ylo",lo)]:
        a.tofile(f"/tmp/ro/{n}_{m}.bin")
G=100000
xg=np.linspace(0,1,G); t64=np.sin(20*xg)+np.exp(xg); hi,lo=hl(ld(xg))
for n,a in [("xg",xg),("tg64",t64),("tghi",hi),("tglo",lo)]:
    a.tofile(f"/tmp/ro/{n}.bin")
