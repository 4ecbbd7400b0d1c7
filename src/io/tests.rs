//! Tests of the CSV and `.npy` readers and writers.

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

use proptest::prelude::*;

use super::*;
use crate::sampling::Domain;

/// A fresh path in the temporary directory.
fn temp_path(name: &str) -> PathBuf {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    std::env::temp_dir().join(format!("rkwave_io_test_{}_{n}_{name}", std::process::id()))
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// Bit-for-bit equality of positions and values.
fn assert_same(a: &SampleSet, b: &SampleSet) {
    assert_eq!(bits(&a.positions), bits(&b.positions));
    assert_eq!(a.channels(), b.channels());
    for c in 0..a.channels() {
        assert_eq!(bits(a.channel(c)), bits(b.channel(c)), "channel {c}");
    }
}

fn example() -> SampleSet {
    SampleSet::new(
        vec![
            0.0,
            -0.0,
            0.1,
            1e-300,
            5e-324,
            -1.7976931348623157e308,
            123456.789,
            1e16,
        ],
        vec![
            vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0],
            vec![
                -0.3,
                1.0 / 3.0,
                2.0f64.sqrt(),
                1e-5,
                9.999e-6,
                0.0,
                -0.0,
                42.0,
            ],
        ],
    )
    .unwrap()
    .with_names(vec!["u".to_string(), "velocity (m/s)".to_string()])
    .unwrap()
}

/// Builds an `.npy` file by hand.
fn npy_by_hand(major: u8, header: &str, data: &[u8]) -> Vec<u8> {
    let mut out = b"\x93NUMPY".to_vec();
    out.extend_from_slice(&[major, 0]);
    let mut header = header.to_string();
    header.push('\n');
    if major == 1 {
        out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    } else {
        out.extend_from_slice(&(header.len() as u32).to_le_bytes());
    }
    out.extend_from_slice(header.as_bytes());
    out.extend_from_slice(data);
    out
}

fn f8_le(values: &[f64]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

#[test]
fn sample_set_basics() {
    let s = example();
    assert_eq!(s.len(), 8);
    assert_eq!(s.channels(), 2);
    assert!(!s.is_empty());
    assert_eq!(s.bounds(), Some((-1.7976931348623157e308, 1e16)));
    assert_eq!(SampleSet::default_names(1), vec!["value"]);
    assert_eq!(SampleSet::default_names(2), vec!["value1", "value2"]);
    assert!(matches!(
        SampleSet::new(vec![1.0, 2.0], vec![vec![1.0]]),
        Err(IoError::InvalidSampleSet { .. })
    ));
    assert!(SampleSet::new(vec![1.0], vec![vec![1.0]])
        .unwrap()
        .with_names(vec![])
        .is_ok());
    assert!(SampleSet::new(vec![1.0], vec![vec![1.0]])
        .unwrap()
        .with_names(vec!["a".into(), "b".into()])
        .is_err());
}

#[test]
fn csv_round_trip_is_exact() {
    let s = example();
    let text = csv_string(&s).unwrap();
    assert!(text.starts_with("x,u,velocity (m/s)\n"), "{text}");
    let back = parse_csv(text.as_bytes(), "mem.csv").unwrap();
    assert_same(&s, &back);
    assert_eq!(back.names, s.names);

    let path = temp_path("round.csv");
    write_csv(&path, &s).unwrap();
    let back = read_csv(&path).unwrap();
    assert_same(&s, &back);
    let back = read_samples(&path).unwrap();
    assert_same(&s, &back);
    std::fs::remove_file(&path).unwrap();
}

#[test]
fn csv_format_is_shortest() {
    assert_eq!(format_f64(0.1), "0.1");
    assert_eq!(format_f64(-0.0), "-0");
    assert_eq!(format_f64(3.0), "3");
    assert_eq!(format_f64(1e-7), "1e-7");
    assert_eq!(format_f64(6.02214076e23), "6.02214076e23");
    assert_eq!(format_f64(5e-324), "5e-324");
}

#[test]
fn csv_reader_is_lenient_about_layout() {
    let text =
        "\u{feff}# comment\r\n\r\n  X , a ,b\r\n # another comment\n 1 , 2,3 \r\n\n-1.5e-3,+4,.5\n";
    let s = parse_csv(text.as_bytes(), "mem.csv").unwrap();
    assert_eq!(s.positions, vec![1.0, -1.5e-3]);
    assert_eq!(s.values, vec![vec![2.0, 4.0], vec![3.0, 0.5]]);
    assert_eq!(s.names, vec!["a", "b"]);
}

#[test]
fn csv_errors_name_file_line_and_fix() {
    let err = parse_csv(b"x,v\n1,2\n3\n", "data/s.csv").unwrap_err();
    let msg = err.to_string();
    assert!(matches!(
        err,
        IoError::ColumnCount {
            line: 3,
            row: 2,
            expected: 2,
            found: 1,
            ..
        }
    ));
    assert!(msg.contains("data/s.csv") && msg.contains("line 3") && msg.contains("row 2"));
    assert!(matches!(
        parse_csv(b"x\n1\n", "f"),
        Err(IoError::BadHeader { line: 1, .. })
    ));
    assert!(matches!(
        parse_csv(b"x,,v\n1,2,3\n", "f"),
        Err(IoError::BadHeader { .. })
    ));
    assert!(matches!(parse_csv(b"", "f"), Err(IoError::Empty { .. })));
    assert!(matches!(
        parse_csv(b"# nothing\n\n", "f"),
        Err(IoError::Empty { .. })
    ));
    let err = parse_csv(b"x,v\n1,1e999\n", "f").unwrap_err();
    assert!(matches!(
        err,
        IoError::NonFinite {
            line: Some(2),
            row: 1,
            column: 2,
            ..
        }
    ));
    assert!(err.to_string().contains("line 2, row 1, column 2"), "{err}");
    assert!(matches!(
        parse_csv(b"x,v\n1,\n", "f"),
        Err(IoError::NotANumber { column: 2, .. })
    ));
}

#[test]
fn csv_writer_rejects_what_it_cannot_read_back() {
    let mut s = SampleSet::new(vec![0.0, 1.0], vec![vec![1.0, f64::NAN]]).unwrap();
    assert!(matches!(
        csv_string(&s),
        Err(IoError::NonFinite {
            row: 2,
            column: 2,
            ..
        })
    ));
    s.values[0][1] = 2.0;
    for bad in ["", " a", "a,b", "a\nb"] {
        s.names = vec![bad.to_string()];
        assert!(
            matches!(csv_string(&s), Err(IoError::InvalidSampleSet { .. })),
            "{bad:?}"
        );
    }
    let none = SampleSet::new(vec![0.0], vec![]).unwrap();
    assert!(matches!(
        csv_string(&none),
        Err(IoError::InvalidSampleSet { .. })
    ));
    // Struct literals without names get the defaults.
    let bare = SampleSet {
        positions: vec![0.5],
        values: vec![vec![1.0]],
        names: vec![],
    };
    assert_eq!(csv_string(&bare).unwrap(), "x,value\n0.5,1\n");
}

#[test]
fn npy_round_trip_is_exact() {
    let s = example();
    let bytes = npy_bytes(&s).unwrap();
    let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    assert_eq!((10 + header_len) % 64, 0);
    assert_eq!(bytes[10 + header_len - 1], b'\n');
    assert_eq!(bytes.len(), 10 + header_len + 8 * 8 * 3);
    let back = parse_npy(&bytes, "mem.npy").unwrap();
    assert_same(&s, &back);
    assert_eq!(back.names, vec!["value1", "value2"]);

    let path = temp_path("round.npy");
    write_npy(&path, &s).unwrap();
    assert_same(&s, &read_npy(&path).unwrap());
    assert_same(&s, &read_samples(&path).unwrap());
    std::fs::remove_file(&path).unwrap();
    let path = temp_path("round2.NPY");
    write_samples(&path, &s).unwrap();
    assert_same(&s, &read_npy(&path).unwrap());
    std::fs::remove_file(&path).unwrap();
}

#[test]
fn npy_reads_f4() {
    let values: [f32; 6] = [0.0, 1.5, 0.1, -2.25, 1.0, 3.0e-3];
    let data: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    let bytes = npy_by_hand(
        1,
        "{'descr': '<f4', 'fortran_order': False, 'shape': (3, 2), }",
        &data,
    );
    let s = parse_npy(&bytes, "f4.npy").unwrap();
    assert_eq!(s.positions, vec![0.0, f64::from(0.1f32), 1.0]);
    assert_eq!(s.values, vec![vec![1.5, -2.25, f64::from(3.0e-3f32)]]);
}

#[test]
fn npy_reads_version_2_and_3() {
    let data = f8_le(&[0.0, 1.0, 0.5, 2.0]);
    let header = "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 2), }";
    for major in [2u8, 3] {
        let bytes = npy_by_hand(major, header, &data);
        assert_eq!(&bytes[8..12], &(header.len() as u32 + 1).to_le_bytes());
        let s = parse_npy(&bytes, "v2.npy").unwrap();
        assert_eq!(s.positions, vec![0.0, 0.5]);
        assert_eq!(s.values, vec![vec![1.0, 2.0]]);
    }
    let bytes = npy_by_hand(4, header, &data);
    assert!(matches!(
        parse_npy(&bytes, "v4.npy"),
        Err(IoError::UnsupportedVersion { major: 4, .. })
    ));
}

#[test]
fn npy_reads_fortran_order_big_endian_and_odd_headers() {
    // Columns stored one after the other: x = [0, 0.5, 1], v = [10, 20, 30].
    let data = f8_le(&[0.0, 0.5, 1.0, 10.0, 20.0, 30.0]);
    let bytes = npy_by_hand(
        1,
        "{'descr': '<f8', 'fortran_order': True, 'shape': (3, 2), }",
        &data,
    );
    let s = parse_npy(&bytes, "f.npy").unwrap();
    assert_eq!(s.positions, vec![0.0, 0.5, 1.0]);
    assert_eq!(s.values, vec![vec![10.0, 20.0, 30.0]]);

    let data: Vec<u8> = [0.0f64, 1.0, 0.5, 2.0]
        .iter()
        .flat_map(|v| v.to_be_bytes())
        .collect();
    // Other key order, double quotes, Python 2 long integers, no trailing comma.
    let bytes = npy_by_hand(
        1,
        "{\"shape\": (2L, 2L), 'fortran_order': False, 'descr': '>f8'}",
        &data,
    );
    let s = parse_npy(&bytes, "be.npy").unwrap();
    assert_eq!(s.positions, vec![0.0, 0.5]);
    assert_eq!(s.values, vec![vec![1.0, 2.0]]);
}

#[test]
fn npy_errors() {
    let data = f8_le(&[0.0, 1.0, 0.5, 2.0]);
    let ok = "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 2), }";
    let mut long = npy_by_hand(1, ok, &data);
    long.extend_from_slice(&[0; 8]);
    assert!(matches!(
        parse_npy(&long, "f"),
        Err(IoError::ShapeMismatch { .. })
    ));
    type Check = fn(&IoError) -> bool;
    let cases: [(&str, Check); 9] = [
        (
            "{'descr': '<f8', 'fortran_order': False, 'shape': (0, 2), }",
            |e| matches!(e, IoError::Empty { .. }),
        ),
        (
            "{'descr': '<f8', 'fortran_order': False, 'shape': (4, 1), }",
            |e| matches!(e, IoError::ShapeMismatch { .. }),
        ),
        (
            "{'descr': '<f8', 'fortran_order': False, 'shape': (1, 2, 2), }",
            |e| matches!(e, IoError::ShapeMismatch { .. }),
        ),
        (
            "{'descr': '<f8', 'fortran_order': False, 'shape': (4611686018427387904, 2), }",
            |e| matches!(e, IoError::ShapeMismatch { .. }),
        ),
        (
            "{'descr': '<f8', 'fortran_order': False, 'shape': (99999999999999999999, 2), }",
            |e| matches!(e, IoError::BadNpyHeader { .. }),
        ),
        (
            "{'descr': '<f8', 'fortran_order': False, 'shape': (-2, 2), }",
            |e| matches!(e, IoError::BadNpyHeader { .. }),
        ),
        (
            "{'descr': [('a', '<f8')], 'fortran_order': False, 'shape': (2,), }",
            |e| matches!(e, IoError::UnsupportedDtype { .. }),
        ),
        ("{'descr': '<f8', 'shape': (2, 2), }", |e| {
            matches!(e, IoError::BadNpyHeader { .. })
        }),
        (
            "{'descr': '<f8', 'fortran_order': Maybe, 'shape': (2, 2), }",
            |e| matches!(e, IoError::BadNpyHeader { .. }),
        ),
    ];
    for (header, check) in cases {
        let err = parse_npy(&npy_by_hand(1, header, &data), "f.npy").unwrap_err();
        assert!(check(&err), "{header}: {err}");
    }
    let deep = format!("{}{}", "(".repeat(10_000), ")".repeat(10_000));
    assert!(matches!(
        parse_npy(&npy_by_hand(1, &deep, &data), "f"),
        Err(IoError::BadNpyHeader { .. })
    ));
    assert!(matches!(parse_npy(b"", "f"), Err(IoError::Empty { .. })));
    assert!(matches!(
        parse_npy(b"\x93NUM", "f"),
        Err(IoError::Truncated { .. })
    ));
    assert!(matches!(
        parse_npy(b"\x93NUMPY\x01\x00\xff", "f"),
        Err(IoError::Truncated { .. })
    ));
    assert!(matches!(
        parse_npy(b"\x93NUMPY\x01\x00\xff\x00{", "f"),
        Err(IoError::Truncated { .. })
    ));
}

#[test]
fn missing_file_is_a_read_error() {
    let path = temp_path("does_not_exist.csv");
    let err = read_samples(&path).unwrap_err();
    assert!(matches!(err, IoError::Read { .. }));
    assert!(err.to_string().contains("does_not_exist.csv"));
    let dir = temp_path("no_such_dir").join("out.csv");
    assert!(matches!(
        write_csv(&dir, &example()),
        Err(IoError::Write { .. })
    ));
}

#[test]
fn validate_positions_reports_the_row() {
    let s = parse_csv(
        include_bytes!("../../data/bad_files/out_of_domain.csv"),
        "out_of_domain.csv",
    )
    .unwrap();
    assert!(validate_positions(&s, Domain::new(0.0, 2.0).unwrap()).is_ok());
    let err = validate_positions(&s, Domain::UNIT).unwrap_err();
    assert!(matches!(
        err,
        IoError::OutOfDomain {
            row: 3,
            value: 1.5,
            ..
        }
    ));
    let msg = err.to_string();
    assert!(
        msg.contains("row 3") && msg.contains("1.5") && msg.contains("[0, 1]"),
        "{msg}"
    );
}

/// Each fixture under `data/bad_files/` and the error it must give.
#[test]
fn bad_fixture_files_give_the_right_errors() {
    macro_rules! fixture {
        ($name:literal) => {
            (
                $name,
                &include_bytes!(concat!("../../data/bad_files/", $name))[..],
            )
        };
    }
    let read = |(name, bytes): (&str, &[u8])| {
        let err = if name.ends_with(".npy") {
            parse_npy(bytes, name)
        } else {
            parse_csv(bytes, name)
        }
        .unwrap_err();
        assert!(err.to_string().contains(name), "{err}");
        err
    };

    let e = read(fixture!("wrong_columns.csv"));
    assert!(
        matches!(
            e,
            IoError::ColumnCount {
                line: 6,
                row: 3,
                expected: 2,
                found: 3,
                ..
            }
        ),
        "{e}"
    );
    let e = read(fixture!("nan_value.csv"));
    assert!(
        matches!(
            &e,
            IoError::NonFinite {
                line: Some(5),
                row: 3,
                column: 2,
                name,
                ..
            } if name == "left"
        ),
        "{e}"
    );
    let e = read(fixture!("inf_value.csv"));
    assert!(
        matches!(
            e,
            IoError::NonFinite {
                line: Some(3),
                row: 2,
                column: 1,
                ..
            }
        ),
        "{e}"
    );
    let e = read(fixture!("no_header.csv"));
    assert!(matches!(e, IoError::MissingHeader { line: 1, .. }), "{e}");
    let e = read(fixture!("bad_header.csv"));
    assert!(matches!(e, IoError::BadHeader { line: 1, .. }), "{e}");
    let e = read(fixture!("not_a_number.csv"));
    assert!(
        matches!(
            &e,
            IoError::NotANumber {
                line: 3,
                row: 2,
                column: 2,
                field,
                ..
            } if field == "abc"
        ),
        "{e}"
    );
    let e = read(fixture!("header_only.csv"));
    assert!(matches!(e, IoError::Empty { .. }), "{e}");
    let e = read(fixture!("not_utf8.csv"));
    assert!(matches!(e, IoError::NotUtf8 { line: 3, .. }), "{e}");

    let e = read(fixture!("truncated.npy"));
    assert!(
        matches!(
            e,
            IoError::Truncated {
                expected: 208,
                found: 176,
                ..
            }
        ),
        "{e}"
    );
    let e = read(fixture!("bad_magic.npy"));
    assert!(matches!(e, IoError::BadMagic { .. }), "{e}");
    let e = read(fixture!("int_dtype.npy"));
    assert!(
        matches!(&e, IoError::UnsupportedDtype { descr, .. } if descr == "<i8"),
        "{e}"
    );
    let e = read(fixture!("one_d.npy"));
    assert!(matches!(e, IoError::ShapeMismatch { .. }), "{e}");
    let e = read(fixture!("nan_value.npy"));
    assert!(
        matches!(
            e,
            IoError::NonFinite {
                line: None,
                row: 2,
                column: 2,
                ..
            }
        ),
        "{e}"
    );
    let e = read(fixture!("bad_header.npy"));
    assert!(matches!(e, IoError::BadNpyHeader { .. }), "{e}");
    let e = read(fixture!("unsupported_version.npy"));
    assert!(
        matches!(e, IoError::UnsupportedVersion { major: 9, .. }),
        "{e}"
    );
}

/// Any finite `f64`, including subnormals and signed zeros.
fn finite() -> impl Strategy<Value = f64> {
    prop_oneof![
        any::<f64>().prop_filter("finite", |x| x.is_finite()),
        Just(0.0),
        Just(-0.0),
        Just(f64::MIN_POSITIVE / 3.0),
        Just(f64::MAX),
        -1e3..1e3f64,
    ]
}

/// A valid sample set: 1..40 rows, 1..4 channels, CSV-safe names.
fn sample_set() -> impl Strategy<Value = SampleSet> {
    (1usize..40, 1usize..4).prop_flat_map(|(m, k)| {
        (
            prop::collection::vec(finite(), m),
            prop::collection::vec(prop::collection::vec(finite(), m), k),
            prop::collection::vec("[a-zA-Zµ_][a-zA-Z0-9_.µ() -]{0,8}[a-z0-9)]", k),
        )
            .prop_map(|(positions, values, names)| SampleSet {
                positions,
                values,
                names,
            })
    })
}

/// A byte edit: (kind, where, byte).
type Edit = (u8, usize, u8);

fn mutate(mut bytes: Vec<u8>, edits: &[Edit]) -> Vec<u8> {
    for &(kind, at, byte) in edits {
        if bytes.is_empty() {
            bytes.push(byte);
            continue;
        }
        let at = at % bytes.len();
        match kind % 5 {
            0 => bytes[at] = byte,
            1 => {
                bytes.remove(at);
            }
            2 => bytes.insert(at, byte),
            3 => bytes.truncate(at),
            _ => bytes[at] ^= 1 << (byte % 8),
        }
    }
    bytes
}

proptest! {
    // 256 cases each by default; set PROPTEST_CASES for a longer fuzz run.
    #[test]
    fn readers_never_panic_on_arbitrary_bytes(bytes in prop::collection::vec(any::<u8>(), 0..300)) {
        let _ = parse_csv(&bytes, "any.csv");
        let _ = parse_npy(&bytes, "any.npy");
        let mut npy = b"\x93NUMPY\x01\x00".to_vec();
        npy.extend_from_slice(&bytes);
        let _ = parse_npy(&npy, "any.npy");
    }

    #[test]
    fn npy_header_parser_never_panics(
        header in "[{}()\\[\\],:' \"<>a-zTFNLruefalsone0-9-]{0,80}",
        major in 1u8..4,
        data in prop::collection::vec(any::<u8>(), 0..64),
    ) {
        let _ = parse_npy(&npy_by_hand(major, &header, &data), "h.npy");
    }

    #[test]
    fn csv_reader_never_panics_on_text(text in "[x0-9.,eE+\\-naifNI# \n\r\t]{0,200}") {
        let _ = parse_csv(text.as_bytes(), "t.csv");
    }

    #[test]
    fn readers_never_panic_on_mutated_files(
        set in sample_set(),
        edits in prop::collection::vec((any::<u8>(), any::<usize>(), any::<u8>()), 1..6),
    ) {
        let csv = mutate(csv_string(&set).unwrap().into_bytes(), &edits);
        let _ = parse_csv(&csv, "m.csv");
        let npy = npy_bytes(&set).unwrap();
        // Aim half the edits at the header, where the parser works hardest.
        let header_edits: Vec<Edit> = edits.iter().map(|&(k, at, b)| (k, at % 128, b)).collect();
        let _ = parse_npy(&mutate(npy.clone(), &edits), "m.npy");
        let _ = parse_npy(&mutate(npy, &header_edits), "m.npy");
    }

    #[test]
    fn valid_sets_round_trip_exactly(set in sample_set()) {
        let back = parse_csv(csv_string(&set).unwrap().as_bytes(), "p.csv").unwrap();
        prop_assert_eq!(bits(&back.positions), bits(&set.positions));
        prop_assert_eq!(&back.names, &set.names);
        for c in 0..set.channels() {
            prop_assert_eq!(bits(back.channel(c)), bits(set.channel(c)));
        }
        let back = parse_npy(&npy_bytes(&set).unwrap(), "p.npy").unwrap();
        prop_assert_eq!(bits(&back.positions), bits(&set.positions));
        for c in 0..set.channels() {
            prop_assert_eq!(bits(back.channel(c)), bits(set.channel(c)));
        }
    }
}
