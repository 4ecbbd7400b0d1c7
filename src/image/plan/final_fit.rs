//! The stopping round's fit, carried so that the plan's final image costs no second solve.
//!
//! The round that stops a plan fits the final set of samples on the final tree (under an
//! iterative solver, continued to the solver's own tolerance: [`crate::image::adaptive::ImagePlan::step`]),
//! and its noise estimate `sigma` is the one its significance test measured. That fit *is* the
//! plan's result: the in-process loop ([`crate::image::adaptive::refine_image`]) makes its
//! output pixels from it. A [`FinalFit`] keeps it (the image channels' coefficients on the
//! tree, the report, `sigma`, and a fingerprint of the samples it was fitted on), so that
//! `plan --final-image`, `reconstruct --dim 2 --state` and Python's `Plan.image()` make their
//! pixels from the same coefficients and `sigma` without fitting again: the three are the same
//! pixels bit for bit, and the in-process loop's.
//!
//! *Which samples.* The fit is used only for samples whose fingerprint
//! `F = sum_i h(x_i, y_i, v_i1, ..., v_iC) mod 2^64` (`h` a 64-bit mix of the bits; order-free,
//! as the plan's positions' fingerprint) and count match the carried ones: the same positions
//! with other values (another render, a denoised copy) are fitted again, with a note.
//!
//! *Bytes.* The plan's folder keeps it in `final.bin` ([`FinalFit::to_bytes`]: the sealed
//! layout of `gram.bin` and `pcg.bin`, tagged with the plan, checksummed). A cache like them:
//! a missing or damaged file means the final image is fitted again (the same tolerance, other
//! bits), said in a note ([`CarriedFinal::note`]).

use crate::image::adaptive::gram::{seal, unseal, GramBytesError, Words};
use crate::image::adaptive::schwarz::SchwarzReport;
use crate::image::adaptive::{mix64, TreeFit, TreeFitReport};
use crate::image::ImageSamples;
use crate::solve::cg::IterationLimit;

/// The first bytes of [`FinalFit::to_bytes`]: the layout's name and version (`02`: the
/// report's `on_limit` after its Schwarz fields; a `01` file is refused as another layout,
/// and the final image fitted again with a note).
const FINAL_MAGIC: &[u8; 8] = b"RKWFIN02";

/// The stopping round's fit of a plan (module docs).
#[derive(Clone, Debug)]
pub struct FinalFit {
    /// Samples fitted (the finite ones).
    pub samples: usize,
    /// Channels of the samples.
    pub channels: usize,
    /// The samples' order-free fingerprint ([`samples_fingerprint`]).
    pub fingerprint: u64,
    /// The noise estimate of the stopping round (0: the noise test is off).
    pub sigma: f64,
    /// The fit: coefficients per image channel (full Mallat layout, zero off the tree) and
    /// its report.
    pub fit: TreeFit,
    /// Why the stopping round fitted by another solver than the plan's (`None`: the plan's).
    pub solver_note: Option<String>,
}

/// The final fit a plan carries, and why the one read from the folder was set aside. Solver
/// state only: two plan states that differ in it are equal.
#[derive(Clone, Debug, Default)]
pub struct CarriedFinal {
    /// The stopping round's fit (`None` while the plan runs, or when set aside).
    pub fit: Option<FinalFit>,
    /// Why the fit read from the folder was not used (damaged, another plan, missing after
    /// the stop); said when the final image is fitted again.
    pub note: Option<String>,
}

impl PartialEq for CarriedFinal {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// The order-free fingerprint `sum_i h(x_i, y_i, v_i1, ..., v_iC) mod 2^64` of `samples`
/// (positions and values, by their bits).
pub fn samples_fingerprint(samples: &ImageSamples) -> u64 {
    let (xs, ys, values) = (samples.xs(), samples.ys(), samples.values());
    (0..xs.len()).fold(0u64, |acc, i| {
        let mut h = mix64(xs[i].to_bits() ^ mix64(ys[i].to_bits()).rotate_left(17));
        for v in values {
            h = mix64(h ^ v[i].to_bits());
        }
        acc.wrapping_add(h)
    })
}

impl FinalFit {
    /// Whether this is the fit of `samples` (count, channels and fingerprint).
    pub fn fits(&self, samples: &ImageSamples) -> bool {
        self.samples == samples.len()
            && self.channels == samples.channels()
            && self.fingerprint == samples_fingerprint(samples)
    }

    /// The fit as bytes (`seal`: `FINAL_MAGIC`, the plan's `tag`, the basis size `n`, the
    /// channels, the samples, their fingerprint, `sigma`, the report's fields, the solver
    /// note, a bit mask of the entries whose bits are not all zero (`-0.0` kept), then each
    /// channel's coefficients there; a checksum).
    pub fn to_bytes(&self, tag: u64) -> Vec<u8> {
        let n = self.fit.coefficients.first().map_or(0, Vec::len);
        let on: Vec<usize> = (0..n)
            .filter(|&f| self.fit.coefficients.iter().any(|c| c[f].to_bits() != 0))
            .collect();
        let mut head = vec![
            n as u64,
            self.fit.coefficients.len() as u64,
            self.samples as u64,
            self.channels as u64,
            self.fingerprint,
            self.sigma.to_bits(),
        ];
        report_words(&self.fit.report, &mut head);
        string_words(self.solver_note.as_deref(), &mut head);
        // bit `f % 64` of word `f / 64` for each entry `f` on: one pass over them
        let mut mask = vec![0u64; n.div_ceil(64)];
        for &f in &on {
            mask[f / 64] |= 1u64 << (f % 64);
        }
        let words = 1 + head.len() + mask.len() + on.len() * self.fit.coefficients.len();
        seal(FINAL_MAGIC, tag, words, |word| {
            word(head.len() as u64);
            head.iter().chain(&mask).for_each(|&w| word(w));
            for c in &self.fit.coefficients {
                on.iter().for_each(|&f| word(c[f].to_bits()));
            }
        })
    }

    /// The fit of [`FinalFit::to_bytes`], if the bytes are whole, carry `tag` and hold
    /// vectors of `n` entries (the plan's basis).
    pub fn from_bytes(bytes: &[u8], tag: u64, n: usize) -> Result<Self, GramBytesError> {
        let mut words = unseal(bytes, FINAL_MAGIC, "final fit", tag)?;
        let head_len = words.next()? as usize;
        if head_len > words.left() {
            return Err(GramBytesError::Damaged("cut short"));
        }
        let head = words.take(head_len)?;
        let mut h = head.iter().copied();
        let mut next = || h.next().ok_or(GramBytesError::Damaged("cut short"));
        let (len, k, samples, channels, fingerprint, sigma) = (
            next()? as usize,
            next()? as usize,
            next()? as usize,
            next()? as usize,
            next()?,
            f64::from_bits(next()?),
        );
        let report = read_report(&mut next)?;
        let solver_note = read_string(&mut next)?;
        if len != n || k != channels {
            return Err(GramBytesError::Damaged("the basis size does not match"));
        }
        let mask = words.take(n.div_ceil(64))?;
        let on: Vec<usize> = (0..n)
            .filter(|&f| (mask[f / 64] >> (f % 64)) & 1 == 1)
            .collect();
        if words.left() as u128 != on.len() as u128 * k as u128 {
            return Err(GramBytesError::Damaged("the sizes do not add up"));
        }
        let coefficients = (0..k)
            .map(|_| spread(&mut words, &on, n))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            samples,
            channels,
            fingerprint,
            sigma,
            fit: TreeFit {
                coefficients,
                report,
            },
            solver_note,
        })
    }
}

/// `on.len()` words put at the indices `on` of a vector of `n` zeros.
fn spread(words: &mut Words<'_>, on: &[usize], n: usize) -> Result<Vec<f64>, GramBytesError> {
    let mut v = vec![0.0; n];
    for (&f, w) in on.iter().zip(words.take(on.len())?) {
        v[f] = f64::from_bits(w);
    }
    Ok(v)
}

/// The report's fields as words, in declaration order (floats by their bits, so NaN and
/// infinities keep theirs).
fn report_words(r: &TreeFitReport, out: &mut Vec<u64>) {
    out.extend([
        r.functions as u64,
        r.samples as u64,
        r.unsampled as u64,
        r.ridge.to_bits(),
        r.min_pivot.to_bits(),
        r.normal_nnz as u64,
        r.factor_nnz as u64,
        r.kernel_s.to_bits(),
        r.normal_s.to_bits(),
        r.normal_kept_functions as u64,
        r.normal_kept_samples as u64,
        r.solve_s.to_bits(),
    ]);
    string_words(Some(&r.solver), out);
    out.extend([
        r.iterations as u64,
        r.relative_residual.to_bits(),
        r.condition.to_bits(),
        u64::from(r.converged),
        u64::from(r.schwarz.is_some()),
    ]);
    let s = r.schwarz.unwrap_or_default();
    out.extend([
        s.blocks as u64,
        s.largest as u64,
        s.overlap.to_bits(),
        s.ridged as u64,
        r.schwarz_setup_s.to_bits(),
        limit_word(r.on_limit),
    ]);
}

/// `on_limit` as a word: 0 none, then [`IterationLimit`]'s variants from 1.
fn limit_word(on_limit: Option<IterationLimit>) -> u64 {
    match on_limit {
        None => 0,
        Some(IterationLimit::Fail) => 1,
        Some(IterationLimit::FallBack) => 2,
        Some(IterationLimit::Accept) => 3,
    }
}

/// The report of [`report_words`].
fn read_report(
    next: &mut impl FnMut() -> Result<u64, GramBytesError>,
) -> Result<TreeFitReport, GramBytesError> {
    let mut r = TreeFitReport {
        functions: next()? as usize,
        samples: next()? as usize,
        unsampled: next()? as usize,
        ridge: f64::from_bits(next()?),
        min_pivot: f64::from_bits(next()?),
        normal_nnz: next()? as usize,
        factor_nnz: next()? as usize,
        kernel_s: f64::from_bits(next()?),
        normal_s: f64::from_bits(next()?),
        normal_kept_functions: next()? as usize,
        normal_kept_samples: next()? as usize,
        solve_s: f64::from_bits(next()?),
        ..TreeFitReport::default()
    };
    r.solver = read_string(next)?.unwrap_or_default();
    r.iterations = next()? as usize;
    r.relative_residual = f64::from_bits(next()?);
    r.condition = f64::from_bits(next()?);
    r.converged = next()? != 0;
    let schwarz = next()? != 0;
    let s = SchwarzReport {
        blocks: next()? as usize,
        largest: next()? as usize,
        overlap: f64::from_bits(next()?),
        ridged: next()? as usize,
    };
    r.schwarz = schwarz.then_some(s);
    r.schwarz_setup_s = f64::from_bits(next()?);
    r.on_limit = match next()? {
        0 => None,
        1 => Some(IterationLimit::Fail),
        2 => Some(IterationLimit::FallBack),
        3 => Some(IterationLimit::Accept),
        _ => {
            return Err(GramBytesError::Damaged(
                "an iteration-limit policy out of range",
            ))
        }
    };
    Ok(r)
}

/// A string as words: its byte length plus one (0: none), then its bytes, 8 a word.
fn string_words(s: Option<&str>, out: &mut Vec<u64>) {
    let Some(s) = s else {
        out.push(0);
        return;
    };
    out.push(s.len() as u64 + 1);
    out.extend(s.as_bytes().chunks(8).map(|c| {
        let mut b = [0u8; 8];
        b[..c.len()].copy_from_slice(c);
        u64::from_le_bytes(b)
    }));
}

/// The string of [`string_words`].
fn read_string(
    next: &mut impl FnMut() -> Result<u64, GramBytesError>,
) -> Result<Option<String>, GramBytesError> {
    let len = next()? as usize;
    if len == 0 {
        return Ok(None);
    }
    let len = len - 1;
    if len > 1 << 20 {
        return Err(GramBytesError::Damaged("a note longer than a megabyte"));
    }
    let mut bytes = Vec::with_capacity(len.next_multiple_of(8));
    for _ in 0..len.div_ceil(8) {
        bytes.extend(next()?.to_le_bytes());
    }
    bytes.truncate(len);
    String::from_utf8(bytes)
        .map(Some)
        .map_err(|_| GramBytesError::Damaged("a note that is not UTF-8"))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bytes give back the fit bit for bit (NaN and infinities in the report included),
    /// and a flipped bit or another plan's tag is refused.
    #[test]
    fn bytes_round_trip() {
        let n = 130;
        let mut c0 = vec![0.0; n];
        let mut c1 = vec![0.0; n];
        for f in [0usize, 3, 64, 65, 129] {
            c0[f] = f as f64 * 0.25 - 1.0;
            c1[f] = -(f as f64);
        }
        let fit = FinalFit {
            samples: 17,
            channels: 2,
            fingerprint: 0xdead_beef_0123_4567,
            sigma: 0.0625,
            fit: TreeFit {
                coefficients: vec![c0, c1],
                report: TreeFitReport {
                    functions: 5,
                    samples: 17,
                    solver: "pcg".into(),
                    condition: f64::NAN,
                    relative_residual: f64::INFINITY,
                    iterations: 9,
                    converged: true,
                    schwarz: Some(SchwarzReport {
                        blocks: 2,
                        largest: 3,
                        overlap: 1.5,
                        ridged: 0,
                    }),
                    on_limit: Some(IterationLimit::FallBack),
                    ..TreeFitReport::default()
                },
            },
            solver_note: Some("a note of 17 bytes".into()),
        };
        let bytes = fit.to_bytes(7);
        let back = FinalFit::from_bytes(&bytes, 7, n).unwrap();
        assert_eq!(back.fit.coefficients, fit.fit.coefficients);
        assert_eq!(
            (back.samples, back.channels, back.fingerprint),
            (17, 2, fit.fingerprint)
        );
        assert_eq!(back.sigma.to_bits(), fit.sigma.to_bits());
        assert_eq!(back.solver_note, fit.solver_note);
        let (a, b) = (&back.fit.report, &fit.fit.report);
        assert_eq!(a.condition.to_bits(), b.condition.to_bits());
        assert_eq!(a.relative_residual, b.relative_residual);
        assert_eq!((a.iterations, a.converged, &a.solver), (9, true, &b.solver));
        assert_eq!(a.schwarz.unwrap().overlap, 1.5);
        assert_eq!(a.on_limit, Some(IterationLimit::FallBack));
        // Every policy and none come back; a file of the layout before `on_limit` (`01`) is
        // refused as another layout (the caller fits the final image again, with a note).
        for on_limit in [
            None,
            Some(IterationLimit::Fail),
            Some(IterationLimit::Accept),
        ] {
            let mut other = fit.clone();
            other.fit.report.on_limit = on_limit;
            let back = FinalFit::from_bytes(&other.to_bytes(7), 7, n).unwrap();
            assert_eq!(back.fit.report.on_limit, on_limit);
        }
        let mut old = bytes.clone();
        old[..8].copy_from_slice(b"RKWFIN01");
        let refused = FinalFit::from_bytes(&old, 7, n).unwrap_err();
        assert!(
            matches!(refused, GramBytesError::Layout { .. }),
            "{refused:?}"
        );
        assert!(refused.to_string().contains("RKWFIN02"), "{refused}");
        assert!(FinalFit::from_bytes(&bytes, 8, n).is_err());
        assert!(FinalFit::from_bytes(&bytes, 7, n + 1).is_err());
        let mut flipped = bytes.clone();
        flipped[40] ^= 1;
        assert!(FinalFit::from_bytes(&flipped, 7, n).is_err());
    }
}
