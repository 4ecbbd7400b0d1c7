//! The streamed single-scale fit (`rkwave::reconstruct::stream`) against the in-memory
//! `fit`: the same coefficients bit for bit when the chunks are merged in the in-memory
//! order, within the QR's rounding bound when merged in another tree, and clear errors.

use rkwave::reconstruct::stream::{fit_streamed, SingleScaleAccumulator, SliceChunks, StreamError};
use rkwave::reconstruct::{fit, single_scale_qr, FitParams, Levels};
use rkwave::sampling::Domain;

/// `m` sorted jittered positions on `[0, 2]` and two channels (smooth and with a kink).
fn samples(m: usize, seed: u64) -> (Vec<f64>, Vec<Vec<f64>>) {
    let mut s = seed;
    let mut next = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let xs: Vec<f64> = (0..m)
        .map(|i| 2.0 * (i as f64 + next()) / m as f64)
        .collect();
    let a = xs.iter().map(|x| (3.0 * x).sin() + 0.01 * next()).collect();
    let b = xs.iter().map(|x| (x - 0.7f64).abs()).collect();
    (xs, vec![a, b])
}

fn bits(v: &[Vec<f64>]) -> Vec<Vec<u64>> {
    v.iter()
        .map(|c| c.iter().map(|x| x.to_bits()).collect())
        .collect()
}

/// Bit-identical coefficients, levels and residual for several chunk sizes (one that
/// divides nothing, one larger than a part), small and multi-part inputs (parts of the
/// in-memory QR start above 2 x 16384 samples when more than one thread runs), p = 2 and 3,
/// automatic and fixed levels.
#[test]
fn streamed_fit_is_bit_identical_to_the_in_memory_fit() {
    let domain = Domain::new(0.0, 2.0).unwrap();
    for (m, p, levels) in [
        (5_000, 3, None),
        (100_003, 3, None),
        (70_000, 2, None),
        (70_000, 3, Some((4, 12))),
    ] {
        let (xs, vals) = samples(m, m as u64);
        let refs: Vec<&[f64]> = vals.iter().map(|v| v.as_slice()).collect();
        let mut params = FitParams {
            p,
            ..FitParams::default()
        };
        if let Some((coarse, fine)) = levels {
            params.levels = Levels::Fixed { coarse, fine };
        }
        let whole = fit(&xs, &refs, domain, &params).unwrap();
        for chunk in [1000, 4093, 60_000] {
            let source = SliceChunks {
                positions: &xs,
                values: &refs,
                chunk,
            };
            let (streamed, report) = fit_streamed(&source, domain, &params).unwrap();
            assert_eq!(
                bits(&streamed.coefficients),
                bits(&whole.coefficients),
                "m {m} chunk {chunk}"
            );
            assert_eq!(
                (streamed.levels.coarse, streamed.levels.fine),
                (whole.levels.coarse, whole.levels.fine)
            );
            assert_eq!(streamed.fallbacks, whole.fallbacks);
            assert!(!report.passes.is_empty());
        }
    }
}

/// Partials of four chunks merged as a balanced tree ((1 2)(3 4)), and through their bytes,
/// against the one-pass QR. Both are backward-stable orthogonal reductions of the same `K_J`,
/// so the coefficients differ by rounding amplified by `cond(K_J)` (about 10 here at
/// oversampling 2-4): 1e-11 of the largest coefficient leaves a margin of 100 over
/// `eps cond(K_J) sqrt(P)`.
#[test]
fn tree_merged_partials_agree_within_the_rounding_bound() {
    let domain = Domain::new(0.0, 2.0).unwrap();
    let (xs, vals) = samples(20_000, 7);
    let refs: Vec<&[f64]> = vals.iter().map(|v| v.as_slice()).collect();
    let basis = FitParams::default().basis(4, 11, domain).unwrap();
    let (whole, _) = single_scale_qr(&basis, &xs, &refs, 0.0).unwrap();
    let cuts = [0, 3_000, 9_000, 15_500, 20_000];
    let partial = |k: usize| {
        let r = cuts[k]..cuts[k + 1];
        let vs: Vec<&[f64]> = refs.iter().map(|v| &v[r.clone()]).collect();
        let mut acc = SingleScaleAccumulator::new(&basis, 2).starting_at(r.start);
        acc.add_chunk(&xs[r], &vs).unwrap();
        SingleScaleAccumulator::from_bytes(&acc.to_bytes(), &basis).unwrap()
    };
    let (mut left, mut right) = (partial(0), partial(2));
    left.merge(partial(1)).unwrap();
    right.merge(partial(3)).unwrap();
    left.merge(right).unwrap();
    assert_eq!(left.samples(), 20_000);
    let (tree, rep) = left.finish(&basis, 0.0).unwrap();
    assert_eq!(rep.deficient, 0);
    for (t, w) in tree.iter().zip(&whole) {
        let scale = w.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let err = t
            .iter()
            .zip(w)
            .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
        assert!(err <= 1e-11 * scale, "{err} vs {scale}");
    }
}

/// Unsorted samples, mismatched channels, merge order and foreign bytes: typed errors that
/// name the sample or the problem.
#[test]
fn bad_streams_are_refused_with_the_fix() {
    let domain = Domain::UNIT;
    let basis = FitParams::default().basis(4, 6, domain).unwrap();
    let mut acc = SingleScaleAccumulator::new(&basis, 1);
    let err = acc
        .add_chunk(&[0.1, 0.9, 0.2], &[&[1.0, 2.0, 3.0]])
        .unwrap_err();
    assert!(
        matches!(err, StreamError::OutOfOrder { row: 3, .. }),
        "{err}"
    );
    assert!(err.to_string().contains("sort"), "{err}");
    let err = acc.add_chunk(&[0.1], &[&[1.0], &[2.0]]).unwrap_err();
    assert!(err.to_string().contains("2 channels"), "{err}");
    let err = acc.add_chunk(&[0.1, 0.2], &[&[1.0, f64::NAN]]).unwrap_err();
    assert!(err.to_string().contains("sample 2"), "{err}");
    let err = acc.add_chunk(&[0.1, 1.5], &[&[1.0, 2.0]]).unwrap_err();
    assert!(err.to_string().contains("1.5"), "{err}");
    let mut late = SingleScaleAccumulator::new(&basis, 1);
    late.add_chunk(&[0.8, 0.9], &[&[1.0, 2.0]]).unwrap();
    let mut early = SingleScaleAccumulator::new(&basis, 1);
    early.add_chunk(&[0.1, 0.2], &[&[1.0, 2.0]]).unwrap();
    let err = late.merge(early).unwrap_err();
    assert!(err.to_string().contains("earlier first"), "{err}");
    let bytes = late.to_bytes();
    for bad in [&b"not a partial"[..], &bytes[..bytes.len() - 8]] {
        let err = SingleScaleAccumulator::from_bytes(bad, &basis)
            .err()
            .unwrap();
        assert!(matches!(err, StreamError::BadBytes { .. }), "{err}");
    }
    let other = FitParams::default().basis(4, 7, domain).unwrap();
    let err = SingleScaleAccumulator::from_bytes(&bytes, &other)
        .err()
        .unwrap();
    assert!(matches!(err, StreamError::BadBytes { .. }), "{err}");
    assert_eq!(err.kind(), rkwave::error::ErrorKind::InvalidInput);
}

/// `finish_fit`: the `Fit` of the accumulated samples, its coefficients those of `finish`
/// and of the in-memory `fit` at the same fixed levels (one accumulator over all samples
/// in order is the in-memory QR's rotations when it runs as one part; the comparison is
/// within the rounding bound of the test above in case it runs as several), the levels and
/// the oversampling `m / 2^{N+1}`; undetermined directions are refused with the fix.
#[test]
fn finish_fit_gives_the_fit_and_refuses_undetermined_directions() {
    let domain = Domain::new(0.0, 2.0).unwrap();
    let (xs, vals) = samples(20_000, 11);
    let refs: Vec<&[f64]> = vals.iter().map(|v| v.as_slice()).collect();
    let basis = FitParams::default().basis(4, 11, domain).unwrap();
    let mut acc = SingleScaleAccumulator::new(&basis, 2);
    acc.add_chunk(&xs, &refs).unwrap();
    let (direct, _) = acc.clone().finish(&basis, 0.0).unwrap();
    let fitted = acc.finish_fit(&basis, 0.0).unwrap();
    assert_eq!(bits(&fitted.coefficients), bits(&direct));
    assert_eq!((fitted.levels.coarse, fitted.levels.fine), (4, 11));
    assert_eq!(fitted.levels.oversampling, 20_000.0 / 4096.0);
    assert!(fitted.fallbacks.is_empty());
    let params = FitParams {
        levels: Levels::Fixed {
            coarse: 4,
            fine: 11,
        },
        ..FitParams::default()
    };
    let whole = fit(&xs, &refs, domain, &params).unwrap();
    for (t, w) in fitted.coefficients.iter().zip(&whole.coefficients) {
        let scale = w.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let err = t
            .iter()
            .zip(w)
            .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
        assert!(err <= 1e-11 * scale, "{err} vs {scale}");
    }
    // The first tenth of the samples leaves most single-scale functions unsampled.
    let mut part = SingleScaleAccumulator::new(&basis, 2);
    let vs: Vec<&[f64]> = refs.iter().map(|v| &v[..2_000]).collect();
    part.add_chunk(&xs[..2_000], &vs).unwrap();
    let err = part.finish_fit(&basis, 0.0).unwrap_err();
    assert!(matches!(err, StreamError::NotStreamable { .. }), "{err}");
    assert!(err.to_string().contains("lower the fine level"), "{err}");
}
