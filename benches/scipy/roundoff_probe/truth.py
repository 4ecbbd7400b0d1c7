# Issue 11: the f64 truth against long double, and FITPACK against the long double truth.
import numpy as np, time
from scipy.interpolate import LSQUnivariateSpline
print(np.finfo(np.longdouble))
def f64(x): return np.sin(20*x)+np.exp(x)
def ld(x):
    X = x.astype(np.longdouble)
    return np.sin(20*X)+np.exp(X)
G=100000
xg=np.linspace(0,1,G)
tl=ld(xg); t64=f64(xg)
rms=lambda a: float(np.sqrt(np.mean(np.asarray(a,dtype=np.longdouble)**2)))
print("truth f64 vs longdouble RMS", rms(t64-tl), "rounded ld vs ld", rms(tl.astype(np.float64)-tl))
for m in [10**5, 10**6]:
    x=np.random.default_rng(0).uniform(0,1,m)
    o=np.argsort(x); xs=x[o]
    P = 32768 if m==10**5 else 262144
    for knots in ["uniform"] + (["quantile"] if m==10**5 else []):
        inner = np.quantile(xs, np.linspace(0,1,P-2)[1:-1]) if knots=="quantile" else np.linspace(0,1,P-2)[1:-1]
        for lab, y in [("f64 samples", f64(xs)), ("rounded-ld samples", ld(xs).astype(np.float64))]:
            s=LSQUnivariateSpline(xs,y,inner,k=3,bbox=[0,1])
            yg=s(xg)
            print(m, knots, lab, "vs f64 truth %.3g  vs ld truth %.3g" % (rms(yg-t64), rms(yg-tl)))
