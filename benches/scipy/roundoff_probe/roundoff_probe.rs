//! Round-off probe of issue 11 (not compiled; see README "least squares at round-off"): isolates
//! the factors of the single-scale fit's error with double-double rows, solve and evaluation.
#![allow(clippy::needless_range_loop)]

use super::eval::Position;
use super::{CdvBasis, Domain, FilterFamily};
use crate::solve::band::GivensTriangle;

#[derive(Clone, Copy, Default, Debug)]
pub(crate) struct Dd(pub f64, pub f64);

#[inline]
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}
#[inline]
fn quick(a: f64, b: f64) -> Dd {
    let s = a + b;
    Dd(s, b - (s - a))
}
impl Dd {
    fn f(x: f64) -> Dd {
        Dd(x, 0.0)
    }
    fn add(self, o: Dd) -> Dd {
        let (s, e) = two_sum(self.0, o.0);
        let (t, f) = two_sum(self.1, o.1);
        let e = e + t;
        let r = quick(s, e);
        quick(r.0, r.1 + f)
    }
    fn neg(self) -> Dd {
        Dd(-self.0, -self.1)
    }
    fn sub(self, o: Dd) -> Dd {
        self.add(o.neg())
    }
    fn mul(self, o: Dd) -> Dd {
        let p = self.0 * o.0;
        let e = self.0.mul_add(o.0, -p);
        quick(p, e + (self.0 * o.1 + self.1 * o.0))
    }
    fn div(self, o: Dd) -> Dd {
        let q1 = self.0 / o.0;
        let r = self.sub(o.mul(Dd::f(q1)));
        let q2 = r.0 / o.0;
        let r = r.sub(o.mul(Dd::f(q2)));
        let q3 = r.0 / o.0;
        quick(q1, q2).add(Dd::f(q3))
    }
    fn sqrt(self) -> Dd {
        let x = self.0.sqrt();
        // One Newton step: x + (a - x^2) / (2x).
        let r = self.sub(Dd::f(x).mul(Dd::f(x)));
        Dd::f(x).add(Dd::f(r.0 / (2.0 * x)))
    }
    fn hi(self) -> f64 {
        self.0 + self.1
    }
}

fn read(path: &str) -> Vec<f64> {
    let b = std::fs::read(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    b.chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

/// Digit tables in double-double for a filter bank.
struct DdTables {
    w: usize,
    bytes: Vec<Dd>,
    v0: Vec<Dd>,
    /// The same byte tables rounded once to f64, and v0 rounded.
    bytes_r: Vec<f64>,
    v0_r: Vec<f64>,
}

fn dd_tables(basis: &CdvBasis) -> DdTables {
    let bank = basis.bank();
    let h = &bank.interior.h;
    let p = bank.p();
    let w = 2 * p - 1;
    let sqrt2 = Dd::f(2.0).sqrt();
    // Sum rules in dd: sum h_even = sum h_odd = 1/sqrt2.
    let half = sqrt2.div(Dd::f(2.0));
    let mut hd: Vec<Dd> = h.iter().map(|&x| Dd::f(x)).collect();
    for par in 0..2 {
        let s = (par..2 * p)
            .step_by(2)
            .fold(Dd::default(), |a, k| a.add(hd[k]));
        let corr = half.sub(s).div(Dd::f(p as f64));
        eprintln!("sum rule parity {par}: defect {:e}", half.sub(s).hi());
        for k in (par..2 * p).step_by(2) {
            hd[k] = hd[k].add(corr);
        }
    }
    let t = |d: usize| -> Vec<Dd> {
        let mut m = vec![Dd::default(); w * w];
        for i in 0..w {
            for l in 0..w {
                let k = 2 * i as i64 + d as i64 - l as i64;
                if (0..2 * p as i64).contains(&k) {
                    m[i * w + l] = sqrt2.mul(hd[k as usize]);
                }
            }
        }
        m
    };
    let tm = [t(0), t(1)];
    let matmul = |a: &[Dd], b: &[Dd]| -> Vec<Dd> {
        let mut c = vec![Dd::default(); w * w];
        for i in 0..w {
            for j in 0..w {
                let mut s = Dd::default();
                for k in 0..w {
                    s = s.add(a[i * w + k].mul(b[k * w + j]));
                }
                c[i * w + j] = s;
            }
        }
        c
    };
    let mut bytes = Vec::with_capacity(256 * w * w);
    for b in 0..256usize {
        let mut pm = vec![Dd::default(); w * w];
        for i in 0..w {
            pm[i * w + i] = Dd::f(1.0);
        }
        for bit in (0..8).rev() {
            pm = matmul(&pm, &tm[(b >> bit) & 1]);
        }
        bytes.extend(pm);
    }
    // v0: power iteration with T_0 from the f64 values, sum 1.
    let mut v: Vec<Dd> = bank.digits.v0.iter().map(|&x| Dd::f(x)).collect();
    for it in 0..400 {
        let mut nv = vec![Dd::default(); w];
        for i in 0..w {
            for l in 0..w {
                nv[i] = nv[i].add(tm[0][i * w + l].mul(v[l]));
            }
        }
        let s = nv.iter().fold(Dd::default(), |a, &x| a.add(x));
        if it == 399 {
            eprintln!("T0 eigenvalue - 1 = {:e}", s.sub(Dd::f(1.0)).hi());
        }
        v = nv.iter().map(|x| x.div(s)).collect();
    }
    let dv: f64 = v
        .iter()
        .zip(&bank.digits.v0)
        .map(|(a, b)| (a.hi() - b).abs())
        .fold(0.0, f64::max);
    eprintln!("v0 f64 vs dd: max diff {dv:e}");
    let dbytes: f64 = bytes
        .iter()
        .zip(&bank.digits.bytes)
        .map(|(a, b)| (a.hi() - b).abs())
        .fold(0.0, f64::max);
    eprintln!("byte tables f64 vs dd: max diff {dbytes:e}");
    DdTables {
        w,
        bytes_r: bytes.iter().map(|x| x.hi()).collect(),
        v0_r: v.iter().map(|x| x.hi()).collect(),
        bytes,
        v0: v,
    }
}

/// Row in dd (interior); None at the edges.
fn dd_row(tab: &DdTables, basis: &CdvBasis, t: f64) -> Option<(usize, Vec<Dd>)> {
    let w = tab.w;
    let p = basis.p();
    let level = basis.coarse();
    let pos = Position::new(t);
    let c = pos.cell(level);
    let right = (1u64 << level) - 1 - c;
    if pos.one || c < w as u64 || right < w as u64 {
        return None;
    }
    let mut a = tab.v0.clone();
    if pos.k > level {
        let bytes = (pos.k - level).div_ceil(8);
        for q in (0..bytes).rev() {
            let byte = pos.byte(level + 1 + 8 * q);
            let m = &tab.bytes[byte * w * w..(byte + 1) * w * w];
            a = (0..w)
                .map(|i| (0..w).fold(Dd::default(), |s, l| s.add(m[i * w + l].mul(a[l]))))
                .collect();
        }
    }
    let scale = Dd::f(basis.amplitude() * 2f64.powf(level as f64 / 2.0));
    Some((
        c as usize + 1 - p,
        (0..w).map(|k| scale.mul(a[w - 1 - k])).collect(),
    ))
}

/// f64 row from tables rounded once (runtime products in f64, same order as production).
fn rounded_row(tab: &DdTables, basis: &CdvBasis, t: f64) -> Option<(usize, Vec<f64>)> {
    let w = tab.w;
    let p = basis.p();
    let level = basis.coarse();
    let pos = Position::new(t);
    let c = pos.cell(level);
    let right = (1u64 << level) - 1 - c;
    if pos.one || c < w as u64 || right < w as u64 {
        return None;
    }
    let mut a = tab.v0_r.clone();
    if pos.k > level {
        let bytes = (pos.k - level).div_ceil(8);
        for q in (0..bytes).rev() {
            let byte = pos.byte(level + 1 + 8 * q);
            let m = &tab.bytes_r[byte * w * w..(byte + 1) * w * w];
            a = (0..w)
                .map(|i| (0..w).fold(0.0, |s, l| s + m[i * w + l] * a[l]))
                .collect();
        }
    }
    let scale = basis.amplitude() * 2f64.powf(level as f64 / 2.0);
    Some((c as usize + 1 - p, (0..w).map(|k| scale * a[w - 1 - k]).collect()))
}

#[derive(Clone, Copy, PartialEq, Debug)]
enum Rows {
    Prod,
    Rounded,
    Dd,
}

fn rows_of(tab: &DdTables, basis: &CdvBasis, xs: &[f64], kind: Rows) -> Vec<(usize, Vec<Dd>)> {
    let mut ev = basis.single_level_evaluator();
    xs.iter()
        .map(|&x| {
            let (f, r) = ev.row_unit(x);
            let prod = (f, r.iter().map(|&v| Dd::f(v)).collect::<Vec<_>>());
            match kind {
                Rows::Prod => prod,
                Rows::Rounded => rounded_row(tab, basis, x)
                    .map(|(f, r)| (f, r.into_iter().map(Dd::f).collect()))
                    .unwrap_or(prod),
                Rows::Dd => dd_row(tab, basis, x).unwrap_or(prod),
            }
        })
        .collect()
}

/// Banded normal equations solved in dd (lower band, half-bandwidth b).
fn dd_solve(n: usize, b: usize, rows: &[(usize, Vec<Dd>)], f: &[Dd]) -> Vec<Dd> {
    let bw = b + 1;
    let mut a = vec![Dd::default(); n * bw];
    let mut r = vec![Dd::default(); n];
    for ((first, row), &fi) in rows.iter().zip(f) {
        for (k, &vk) in row.iter().enumerate() {
            let i = first + k;
            for l in 0..=k {
                a[i * bw + (k - l)] = a[i * bw + (k - l)].add(vk.mul(row[l]));
            }
            r[i] = r[i].add(vk.mul(fi));
        }
    }
    // Cholesky.
    for j in 0..n {
        let lo = j.saturating_sub(b);
        let mut s = a[j * bw];
        for k in lo..j {
            let l = a[j * bw + (j - k)];
            s = s.sub(l.mul(l));
        }
        assert!(s.0 > 0.0, "pivot {j}");
        let ljj = s.sqrt();
        a[j * bw] = ljj;
        for i in (j + 1)..n.min(j + b + 1) {
            let mut t = a[i * bw + (i - j)];
            for k in i.saturating_sub(b).max(lo)..j {
                t = t.sub(a[i * bw + (i - k)].mul(a[j * bw + (j - k)]));
            }
            a[i * bw + (i - j)] = t.div(ljj);
        }
    }
    for i in 0..n {
        let mut t = r[i];
        for k in i.saturating_sub(b)..i {
            t = t.sub(a[i * bw + (i - k)].mul(r[k]));
        }
        r[i] = t.div(a[i * bw]);
    }
    for i in (0..n).rev() {
        let mut t = r[i];
        for k in (i + 1)..n.min(i + b + 1) {
            t = t.sub(a[k * bw + (k - i)].mul(r[k]));
        }
        r[i] = t.div(a[i * bw]);
    }
    r
}

fn qr_solve(n: usize, w: usize, rows: &[(usize, Vec<Dd>)], f: &[Dd], chunks: usize) -> Vec<Dd> {
    let rows64: Vec<(usize, Vec<f64>)> = rows
        .iter()
        .map(|(a, r)| (*a, r.iter().map(|x| x.hi()).collect()))
        .collect();
    let mut tri = GivensTriangle::new(0, n, w, 1);
    let per = rows.len().div_ceil(chunks);
    for c in 0..chunks {
        let range = c * per..((c + 1) * per).min(rows.len());
        let mut part = GivensTriangle::new(0, n, w, 1);
        for i in range {
            part.add_row(rows64[i].0, &rows64[i].1, &[f[i].hi()]);
        }
        if chunks == 1 {
            tri = part;
        } else {
            tri.absorb(&part);
        }
    }
    let sol = tri.solve(1e-10);
    sol.coefficients[0].iter().map(|&x| Dd::f(x)).collect()
}

fn rms_err(
    basis: &CdvBasis,
    tab: &DdTables,
    v: &[Dd],
    xg: &[f64],
    truth: &[Dd],
    eval_dd: bool,
    rows: Rows,
) -> f64 {
    let g = rows_of(tab, basis, xg, rows);
    let mut s = 0.0;
    for ((first, row), t) in g.iter().zip(truth) {
        let val = if eval_dd {
            row.iter()
                .enumerate()
                .fold(Dd::default(), |a, (k, r)| a.add(r.mul(v[first + k])))
        } else {
            Dd::f(
                row.iter()
                    .enumerate()
                    .map(|(k, r)| r.hi() * v[first + k].hi())
                    .sum::<f64>(),
            )
        };
        let e = val.sub(*t).hi();
        s += e * e;
    }
    (s / xg.len() as f64).sqrt()
}

#[test]
fn probe() {
    let m: usize = std::env::var("PROBE_M").map_or(1_000_000, |s| s.parse().unwrap());
    let ps: Vec<usize> = std::env::var("PROBE_P").map_or(vec![6], |s| {
        s.split(',').map(|x| x.parse().unwrap()).collect()
    });
    let d = "/tmp/ro";
    let x = read(&format!("{d}/x_{m}.bin"));
    let y64 = read(&format!("{d}/y64_{m}.bin"));
    let yhi = read(&format!("{d}/yhi_{m}.bin"));
    let ylo = read(&format!("{d}/ylo_{m}.bin"));
    let xg = read(&format!("{d}/xg.bin"));
    let tg64 = read(&format!("{d}/tg64.bin"));
    let tghi = read(&format!("{d}/tghi.bin"));
    let tglo = read(&format!("{d}/tglo.bin"));
    let tdd: Vec<Dd> = tghi.iter().zip(&tglo).map(|(&a, &b)| Dd(a, b)).collect();
    let t64: Vec<Dd> = tg64.iter().map(|&a| Dd::f(a)).collect();
    let fdd: Vec<Dd> = yhi.iter().zip(&ylo).map(|(&a, &b)| Dd(a, b)).collect();
    let f64v: Vec<Dd> = y64.iter().map(|&a| Dd::f(a)).collect();
    let frnd: Vec<Dd> = yhi.iter().map(|&a| Dd::f(a)).collect();
    let j = if m == 1_000_000 { 18 } else { 15 };
    for p in ps {
        let basis = CdvBasis::new(p, FilterFamily::cdv_default(p), j, j, Domain::UNIT).unwrap();
        let n = basis.dimension() / 2;
        let b = 3 * p - 3;
        let tab = dd_tables(&basis);
        // Row accuracy.
        let rp = rows_of(&tab, &basis, &x, Rows::Prod);
        let rr = rows_of(&tab, &basis, &x, Rows::Rounded);
        let rd = rows_of(&tab, &basis, &x, Rows::Dd);
        let row_err = |a: &[(usize, Vec<Dd>)]| {
            let (mut s, mut c, mut mx) = (0.0, 0usize, 0.0f64);
            for ((_, ra), (_, rb)) in a.iter().zip(&rd) {
                for (u, v) in ra.iter().zip(rb) {
                    let e = u.sub(*v).hi() / 2f64.powf(j as f64 / 2.0);
                    s += e * e;
                    c += 1;
                    mx = mx.max(e.abs());
                }
            }
            ((s / c as f64).sqrt(), mx)
        };
        eprintln!(
            "p={p} m={m}: row error (units of phi, not phi_J): prod {:?}, rounded tables {:?}",
            row_err(&rp),
            row_err(&rr)
        );
        let report = |name: &str, v: &[Dd]| {
            let e_dd = rms_err(&basis, &tab, v, &xg, &tdd, true, Rows::Dd);
            let e_prod = rms_err(&basis, &tab, v, &xg, &tdd, false, Rows::Prod);
            let e_rnd = rms_err(&basis, &tab, v, &xg, &tdd, false, Rows::Rounded);
            let e_prod64 = rms_err(&basis, &tab, v, &xg, &t64, false, Rows::Prod);
            eprintln!(
                "p={p} m={m} {name:40}: grid eval dd {e_dd:.3e} | f64 prod rows {e_prod:.3e} | f64 rounded-table rows {e_rnd:.3e} | prod vs f64 truth {e_prod64:.3e}"
            );
        };
        let v = dd_solve(n, b, &rd, &fdd);
        report("dd rows, dd solve, dd rhs", &v);
        let v = dd_solve(n, b, &rd, &frnd);
        report("dd rows, dd solve, rounded rhs", &v);
        let v = dd_solve(n, b, &rd, &f64v);
        report("dd rows, dd solve, f64-formula rhs", &v);
        let v = dd_solve(n, b, &rp, &frnd);
        report("prod rows, dd solve, rounded rhs", &v);
        let v = dd_solve(n, b, &rr, &frnd);
        report("rounded-table rows, dd solve, rounded rhs", &v);
        for chunks in [1, 2, 8] {
            let v = qr_solve(n, b + 1, &rd, &frnd, chunks);
            report(&format!("dd rows, f64 QR x{chunks}, rounded rhs"), &v);
        }
        let v = qr_solve(n, b + 1, &rp, &frnd, 2);
        report("prod rows, f64 QR x2, rounded rhs", &v);
        let v = qr_solve(n, b + 1, &rp, &f64v, 2);
        report("prod rows, f64 QR x2, f64-formula rhs", &v);
        let v = qr_solve(n, b + 1, &rr, &frnd, 2);
        report("rounded-table rows, f64 QR x2, rounded rhs", &v);
    }
}
