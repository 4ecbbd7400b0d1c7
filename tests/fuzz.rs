//! Fuzzing under proptest: the sample readers (CSV, `.npy`; 1D and the image plane's), the
//! plan state reader, the expression and domain parsers, and the command line's argument
//! space. Each property: no panic, and either a
//! typed error or a valid result (finite positions, consistent lengths); the binary exits
//! with 0, 1 or 2 and never prints a panic report. Case counts are fixed so the whole file
//! runs in well under a minute on the CI machine.

mod common;

use std::time::Duration;

use proptest::prelude::*;
use rkwave::image::adaptive::AdaptiveParams;
use rkwave::image::plan::PlanState;
use rkwave::io::{parse_csv, read_samples};
use rkwave::refine::{ExpressionOracle, SampleOracle};
use rkwave::sampling::Domain;

/// Pieces CSV files are made of, hostile ones included.
fn csv_piece() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("x".to_string()),
        Just("y".to_string()),
        Just(",".to_string()),
        Just("\n".to_string()),
        Just("\r".to_string()),
        Just("\r\n".to_string()),
        Just("#".to_string()),
        Just(" ".to_string()),
        Just("\"".to_string()),
        Just("\u{feff}".to_string()),
        Just("nan".to_string()),
        Just("inf".to_string()),
        Just("-1e308".to_string()),
        Just("1e-320".to_string()),
        Just("é".to_string()),
        any::<f64>().prop_map(|v| format!("{v}")),
        (0u32..100).prop_map(|v| v.to_string()),
    ]
}

fn check_set(set: &rkwave::io::SampleSet) {
    assert!(!set.positions.is_empty());
    assert!(set.positions.iter().all(|x| x.is_finite()));
    for ch in &set.values {
        assert_eq!(ch.len(), set.positions.len());
        assert!(ch.iter().all(|v| v.is_finite()));
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn csv_reader_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
        if let Ok(set) = parse_csv(&bytes, "fuzz.csv") {
            check_set(&set);
        }
    }

    #[test]
    fn csv_reader_on_csv_like_text(pieces in proptest::collection::vec(csv_piece(), 0..40)) {
        let text: String = pieces.concat();
        let text = format!("x,y\n{text}");
        if let Ok(set) = parse_csv(text.as_bytes(), "fuzz.csv") {
            check_set(&set);
        }
    }

    #[test]
    fn expression_parser_never_panics(
        tokens in proptest::collection::vec(
            prop_oneof![
                Just("x"), Just("-"), Just("+"), Just("*"), Just("/"), Just("^"), Just("("),
                Just(")"), Just(","), Just("1e3"), Just("2"), Just(".5"), Just("e"), Just("E"),
                Just("PI"), Just("sin"), Just("exp"), Just("min"), Just("atan2"), Just("<"),
                Just(">="), Just("=="), Just("!="), Just(" "), Just("1e"), Just("ä"),
                Just("sqrt"), Just("y"), Just("1e400"),
            ],
            0..30,
        ),
        x in -10.0f64..10.0,
    ) {
        let text: String = tokens.concat();
        match ExpressionOracle::parse(&text) {
            Ok(e) => {
                let _ = e.sample(x); // any f64, NaN included: the refiner reports those
            }
            Err(err) => {
                let msg = err.to_string();
                prop_assert!(!msg.is_empty() && msg.len() < 1000, "{}", msg);
            }
        }
    }

    #[test]
    fn domain_parser_never_panics(text in "[-0-9.,e+ infa]{0,30}") {
        if let Ok(d) = text.parse::<Domain>() {
            prop_assert!(d.a().is_finite() && d.b().is_finite() && d.a() < d.b());
        }
    }
}

/// A little-endian `<f8` `.npy` file of shape `(rows, cols)`.
fn npy(rows: usize, cols: usize, data: &[f64], descr: &str) -> Vec<u8> {
    let mut header =
        format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': ({rows}, {cols}), }}");
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    /// Valid files with flipped bytes, truncations and odd shapes, through the public reader.
    #[test]
    fn npy_reader_never_panics(
        rows in 0usize..6,
        cols in 0usize..4,
        data in proptest::collection::vec(any::<f64>(), 0..24),
        flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 0..4),
        cut in proptest::option::of(any::<usize>()),
        descr in prop_oneof![Just("<f8"), Just(">f8"), Just("<f4"), Just("<i8"), Just("|u1")],
    ) {
        let mut bytes = npy(rows, cols, &data, descr);
        for (at, b) in flips {
            let i = at % bytes.len();
            bytes[i] ^= b;
        }
        if let Some(c) = cut {
            bytes.truncate(c % (bytes.len() + 1));
        }
        let path = std::env::temp_dir().join(format!(
            "rkwave-fuzz-{}-{:?}.npy",
            std::process::id(),
            std::thread::current().id()
        ));
        std::fs::write(&path, &bytes).unwrap();
        if let Ok(set) = read_samples(&path) {
            check_set(&set);
        }
        let _ = std::fs::remove_file(&path);
    }
}

/// A scratch file of this process and thread with extension `ext`.
fn fuzz_file(ext: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!(
        "rkwave-fuzz-{}-{:?}.{ext}",
        std::process::id(),
        std::thread::current().id()
    ))
}

/// Image samples read from a file: on the plane, finite, one value per channel and sample.
fn check_image_samples(s: &rkwave::image::ImageSamples, w: usize, h: usize) {
    assert!(!s.is_empty() && (1..=4).contains(&s.channels()));
    for (x, y) in s.xs().iter().zip(s.ys()) {
        assert!((0.0..=w as f64).contains(x) && (0.0..=h as f64).contains(y));
    }
    for c in s.values() {
        assert_eq!(c.len(), s.len());
        assert!(c.iter().all(|v| v.is_finite()));
    }
}

/// A value a tampered plan state may hold in place of one of its own.
fn json_value() -> impl Strategy<Value = serde_json::Value> {
    use serde_json::json;
    prop_oneof![
        Just(json!(null)),
        Just(json!(-1)),
        Just(json!(0)),
        Just(json!(1e308)),
        Just(json!(u64::MAX)),
        Just(json!("zz")),
        Just(json!("ffffffffffffffffff")),
        Just(json!([])),
        Just(json!({})),
        Just(json!(true)),
        (0u32..100_000).prop_map(|v| json!(v)),
        any::<f64>().prop_map(|v| json!(v)),
    ]
}

/// Every leaf of a JSON value, as a JSON pointer.
fn leaves(v: &serde_json::Value, at: String, out: &mut Vec<String>) {
    match v {
        serde_json::Value::Object(m) => {
            for (k, x) in m {
                leaves(x, format!("{at}/{k}"), out);
            }
        }
        serde_json::Value::Array(a) if !a.is_empty() => {
            for (i, x) in a.iter().enumerate() {
                leaves(x, format!("{at}/{i}"), out);
            }
        }
        _ => out.push(at),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// The image plane's sample reader (`.npy` and CSV, 2 to 7 columns, values and positions
    /// anywhere, bytes flipped): a typed error or samples on the plane, never a panic.
    #[test]
    fn image_sample_reader_never_panics(
        rows in 0usize..8,
        cols in 0usize..8,
        data in proptest::collection::vec(
            prop_oneof![any::<f64>(), -2.0..20.0f64, Just(f64::NAN)], 0..56),
        flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 0..3),
        as_npy in any::<bool>(),
        w in 1usize..20,
        h in 1usize..20,
    ) {
        let (path, mut bytes) = if as_npy {
            (fuzz_file("npy"), npy(rows, cols, &data, "<f8"))
        } else {
            let mut text = String::from("x,y,v\n");
            for row in data.chunks(cols.max(1)) {
                let cells: Vec<String> = row.iter().map(|v| v.to_string()).collect();
                text.push_str(&cells.join(","));
                text.push('\n');
            }
            (fuzz_file("csv"), text.into_bytes())
        };
        for (at, b) in flips {
            if !bytes.is_empty() {
                let i = at % bytes.len();
                bytes[i] ^= b;
            }
        }
        std::fs::write(&path, &bytes).unwrap();
        let plane = rkwave::image::ImagePlane::new(w, h).unwrap();
        if let Ok(s) = rkwave::io::read_image_samples(&path, plane) {
            check_image_samples(&s, w, h);
        }
        let _ = std::fs::remove_file(&path);
    }

    /// The plan state reader on arbitrary bytes: a typed error, never a panic.
    #[test]
    fn plan_state_reader_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
        let text = String::from_utf8_lossy(&bytes);
        let _ = PlanState::from_json(&text, std::path::Path::new("state.json"));
    }

    /// A valid plan state with one field replaced by a hostile value: read back or refused
    /// with a typed error; a state read back can still be checked against its own plane.
    #[test]
    fn plan_state_reader_on_tampered_states(pick in any::<usize>(), value in json_value()) {
        let plane = rkwave::image::ImagePlane::new(16, 16).unwrap();
        let mut params = AdaptiveParams::default();
        params.stop.budget = 1024;
        let (state, _) = PlanState::start(plane, &params).unwrap();
        let mut json: serde_json::Value = serde_json::from_str(&state.to_json()).unwrap();
        let mut paths = Vec::new();
        leaves(&json, String::new(), &mut paths);
        let at = &paths[pick % paths.len()];
        *json.pointer_mut(at).unwrap() = value;
        if let Ok(back) = PlanState::from_json(&json.to_string(), std::path::Path::new("state.json")) {
            let _ = back.check_params(back.plane, &back.params);
        }
    }
}

/// Values a flag may receive, the absurd included.
fn value() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("0".to_string()),
        Just("1".to_string()),
        Just("2".to_string()),
        Just("3".to_string()),
        Just("8".to_string()),
        Just("60".to_string()),
        Just("-1".to_string()),
        Just("18446744073709551615".to_string()),
        Just("1e308".to_string()),
        Just("1e-308".to_string()),
        Just("nan".to_string()),
        Just("inf".to_string()),
        Just("0,1".to_string()),
        Just("1,0".to_string()),
        Just("-1e308,1e308".to_string()),
        Just("4..9".to_string()),
        Just("60..60".to_string()),
        Just("auto".to_string()),
        Just("".to_string()),
        Just("smooth".to_string()),
        Just("-x^2".to_string()),
        Just("svd".to_string()),
        Just("cholesky".to_string()),
        Just("local".to_string()),
        Just("/proc/rkwave-fuzz/o.png".to_string()),
    ]
}

fn flag() -> impl Strategy<Value = &'static str> {
    prop_oneof![
        Just("--p"),
        Just("--coarse"),
        Just("--fine"),
        Just("--domain"),
        Just("--points"),
        Just("--samples"),
        Just("--rings"),
        Just("--solver"),
        Just("--cutoff"),
        Just("--grid"),
        Just("--levels"),
        Just("--rho"),
        Just("--signal"),
        Just("--layout"),
        Just("--probes"),
        Just("--max-depth"),
        Just("--budget"),
        Just("--tolerance"),
        Just("--x"),
        Just("--plot"),
        Just("--method"),
        Just("--family"),
        Just("--json"),
        Just("--seed"),
    ]
}

fn subcommand() -> impl Strategy<Value = &'static str> {
    prop_oneof![
        Just("basis"),
        Just("eval"),
        Just("report"),
        Just("adapt"),
        Just("reconstruct")
    ]
}

proptest! {
    // Each case starts the binary once (tens of milliseconds); 150 cases take ~10-30 s.
    #![proptest_config(ProptestConfig::with_cases(150))]

    #[test]
    fn the_command_line_exits_0_1_or_2_and_never_panics(
        sub in subcommand(),
        pairs in proptest::collection::vec((flag(), value()), 0..5),
    ) {
        let mut args = vec![sub.to_string()];
        if sub == "reconstruct" {
            // an input that exists and an output that does not
            let input = std::env::temp_dir().join("rkwave-fuzz-in.csv");
            std::fs::write(&input, "x,y\n0.1,1\n0.3,2\n0.5,0\n0.7,1\n0.9,3\n").unwrap();
            args.extend(["--input".into(), input.display().to_string()]);
            args.extend(["--output".into(), "/proc/rkwave-fuzz/o.csv".into()]);
        }
        if sub == "adapt" {
            // small runs (a repeated flag is itself a user error, exit 2)
            args.extend(["--budget", "3000", "--grid", "2048", "--round-grid", "0"].map(String::from));
        }
        for (f, v) in pairs {
            args.push(f.to_string());
            if f != "--json" {
                args.push(v);
            }
        }
        args.extend(["--memory-limit", "1G"].map(String::from));
        let Some((code, err)) = common::rkwave_bounded(&args, Duration::from_secs(30)) else {
            return Err(TestCaseError::fail(format!("{args:?} ran past 30 s")));
        };
        prop_assert!(matches!(code, 0..=2), "{:?} exited {}: {}", args, code, err);
        prop_assert!(!err.contains("panicked"), "{:?}: {}", args, err);
    }
}
