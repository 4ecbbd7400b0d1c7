//! The `.npy` reader against files written by NumPy itself (`data/fixtures/npy/`, made by
//! `make_fixtures.py` there; `expected.json` beside them states what each must give).
//!
//! Readable fixtures must come back bit for bit (float32 is widened exactly, so its bits are
//! exact too); malformed ones must give the named typed error, with a message that names the
//! file. Nothing here is written by rkwave's own writer, so a reader and writer that agree on a
//! wrong format cannot pass.

use std::path::{Path, PathBuf};

use rkwave::io::{npy_bytes, parse_npy, read_npy, read_samples, IoError, SampleSet};
use serde_json::Value;

fn dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/fixtures/npy")
}

fn expected() -> Value {
    let text = std::fs::read_to_string(dir().join("expected.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// The columns of a set: positions, then each channel.
fn columns(set: &SampleSet) -> Vec<Vec<u64>> {
    std::iter::once(&set.positions)
        .chain(set.values.iter())
        .map(|c| c.iter().map(|v| v.to_bits()).collect())
        .collect()
}

fn bits(column: &Value) -> Vec<u64> {
    column
        .as_array()
        .unwrap()
        .iter()
        .map(|h| u64::from_str_radix(h.as_str().unwrap().trim_start_matches("0x"), 16).unwrap())
        .collect()
}

/// The variant's name, as `expected.json` spells it.
fn variant(e: &IoError) -> &'static str {
    match e {
        IoError::Truncated { .. } => "Truncated",
        IoError::ShapeMismatch { .. } => "ShapeMismatch",
        IoError::BadMagic { .. } => "BadMagic",
        IoError::Empty { .. } => "Empty",
        IoError::UnsupportedDtype { .. } => "UnsupportedDtype",
        IoError::NonFinite { .. } => "NonFinite",
        IoError::BadNpyHeader { .. } => "BadNpyHeader",
        IoError::UnsupportedVersion { .. } => "UnsupportedVersion",
        _ => "other",
    }
}

#[test]
fn every_fixture_written_by_numpy_reads_as_stated() {
    let expected = expected();
    let files = expected["files"].as_object().unwrap();
    assert!(files.len() >= 25, "{} fixtures", files.len());
    let (mut readable, mut malformed) = (0, 0);
    for (name, spec) in files {
        let path = dir().join(name);
        match spec.get("error") {
            None => {
                let set = read_npy(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
                let want: Vec<Vec<u64>> = spec["columns"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(bits)
                    .collect();
                assert_eq!(columns(&set), want, "{name}");
                // The generic entry point picks the .npy reader by extension.
                assert_eq!(read_samples(&path).unwrap(), set, "{name}");
                readable += 1;
            }
            Some(error) => {
                let err = read_npy(&path).expect_err(name);
                assert_eq!(variant(&err), error.as_str().unwrap(), "{name}: {err}");
                let message = err.to_string();
                assert!(message.contains(name.as_str()), "{message}");
                malformed += 1;
            }
        }
    }
    assert_eq!((readable, malformed), (10, 16));
}

/// The stated formulas, recomputed: the fixtures hold x_i = i/10 and sin(3 x_i) - 1/3, so a
/// fixture set regenerated wrongly (or a JSON that drifted from it) is caught too.
#[test]
fn fixtures_hold_the_stated_samples() {
    let set = read_npy(dir().join("f8_fortran.npy")).unwrap();
    for (i, (&x, (&v1, &v2))) in set
        .positions
        .iter()
        .zip(set.values[0].iter().zip(&set.values[1]))
        .enumerate()
    {
        let xi = i as f64 / 10.0;
        assert_eq!(x, xi);
        // NumPy's sin and Rust's may differ in the last bit: 2 ulp of values below 1.
        assert!((v1 - ((3.0 * xi).sin() - 1.0 / 3.0)).abs() <= 4.0 * f64::EPSILON);
        assert_eq!(v2, 1e-300 * (i as f64 + 1.0));
    }
    // float32: every value is the float32 nearest the float64 one, widened exactly.
    let f4 = read_npy(dir().join("f4_c_be.npy")).unwrap();
    let f8 = read_npy(dir().join("f8_c_le.npy")).unwrap();
    for (a, b) in columns(&f4).iter().zip(columns(&f8)) {
        for (&a, b) in a.iter().zip(b) {
            assert_eq!(f64::from_bits(a), f64::from(f64::from_bits(b) as f32));
        }
    }
}

#[test]
fn malformed_fixtures_say_what_is_wrong() {
    let err = |name: &str| read_npy(dir().join(name)).unwrap_err();
    // Truncated data: 5 x 2 float64 after a 128-byte preamble need 208 bytes; 196 are there.
    assert!(matches!(
        err("m_truncated.npy"),
        IoError::Truncated {
            expected: 208,
            found: 196,
            ..
        }
    ));
    assert!(matches!(
        err("m_header_cut.npy"),
        IoError::Truncated { found: 40, .. }
    ));
    let e = err("m_trailing.npy");
    assert!(e.to_string().contains("8 bytes are left over"), "{e}");
    for (name, descr) in [
        ("m_int64.npy", "<i8"),
        ("m_int32.npy", "<i4"),
        ("m_float16.npy", "<f2"),
        ("m_complex.npy", "<c16"),
        ("m_object.npy", "|O"),
    ] {
        let e = err(name);
        assert!(
            matches!(&e, IoError::UnsupportedDtype { descr: d, .. } if d == descr),
            "{name}: {e}"
        );
        assert!(e.to_string().contains("astype('<f8')"), "{e}");
    }
    let e = err("m_structured.npy");
    assert!(
        e.to_string().contains("structured dtype with 2 fields"),
        "{e}"
    );
    let e = err("m_one_d.npy");
    assert!(
        e.to_string().contains("shape (5,), which is not 2-D"),
        "{e}"
    );
    let e = err("m_three_d.npy");
    assert!(e.to_string().contains("(2, 2, 2)"), "{e}");
    let e = err("m_one_column.npy");
    assert!(e.to_string().contains("1 column(s)"), "{e}");
    assert!(matches!(
        err("m_nan.npy"),
        IoError::NonFinite {
            line: None,
            row: 4,
            column: 2,
            ..
        }
    ));
    let e = err("m_inf.npy");
    assert!(
        matches!(
            &e,
            IoError::NonFinite { line: None, row: 2, column: 1, value, .. } if *value == f64::NEG_INFINITY
        ),
        "{e}"
    );
}

/// Our writer's file is NumPy's file up to the spelling of the shape tuple (`npyz` writes
/// `(5, 2, )`, NumPy `(5, 2)`; both are the same Python literal): the same length, the same
/// 64-byte-aligned header, the same data bytes, and both read as the same samples.
#[test]
fn writer_matches_numpy_up_to_the_header_spelling() {
    let numpy = std::fs::read(dir().join("f8_c_le.npy")).unwrap();
    let set = parse_npy(&numpy, "f8_c_le.npy").unwrap();
    let ours = npy_bytes(&set).unwrap();
    assert_eq!(ours.len(), numpy.len());
    assert_eq!(ours[..10], numpy[..10], "magic, version and header length");
    assert_eq!(ours[128..], numpy[128..], "data");
    let header = |b: &[u8]| -> String {
        String::from_utf8(b[10..128].to_vec())
            .unwrap()
            .replace(", )", ")")
            .replace(' ', "")
    };
    assert_eq!(header(&ours), header(&numpy));
    assert_eq!(parse_npy(&ours, "ours.npy").unwrap(), set);
}
