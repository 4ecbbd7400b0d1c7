//! The streamed 1D fit through the binary and the chunked reader it reads with: the same
//! output file bit for bit as the in-memory path, from a `.npy` and from a CSV input; a CSV
//! file read in ranges of rows gives the rows of the whole-file parser; streams that cannot
//! work are refused before any work, naming the fix.

mod common;

use std::path::Path;

use common::{scratch, succeeds, user_error};
use rkwave::io::chunks::SampleChunkReader;
use rkwave::io::{parse_csv, write_csv, write_npy, IoError, SampleSet};

/// `m` sorted positions in [0, 2) and two smooth channels with a kink (a fit with several
/// QR parts when `m` is above 32,768).
fn sorted_samples(m: usize) -> SampleSet {
    let positions: Vec<f64> = (0..m)
        .map(|i| 2.0 * (i as f64 + 0.5 * (((i * 7919) % 1000) as f64 / 1000.0)) / m as f64)
        .collect();
    let a = positions
        .iter()
        .map(|x| (3.0 * x).sin() + (x - 1.1).abs())
        .collect();
    let b = positions.iter().map(|x| x * x - 0.5 * x).collect();
    SampleSet::new(positions, vec![a, b]).unwrap()
}

/// `reconstruct --input INPUT --output OUTPUT --stream STREAM` and `extra`.
fn args<'a>(input: &'a Path, output: &'a Path, stream: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
    let mut a = vec![
        "reconstruct",
        "--input",
        input.to_str().unwrap(),
        "--output",
        output.to_str().unwrap(),
        "--stream",
        stream,
    ];
    a.extend_from_slice(extra);
    a
}

fn run(input: &Path, output: &Path, stream: &str) -> String {
    succeeds(&args(input, output, stream, &["--domain", "0,2"]))
}

/// The same grid file, byte for byte, streamed (`always`) and read whole (`never`), for a
/// `.npy` and a CSV input of 70,000 samples (more than one QR part and one 64 Ki chunk).
#[test]
fn streamed_output_is_the_in_memory_output_bit_for_bit() {
    let dir = scratch("stream-cli", "identical");
    let set = sorted_samples(70_000);
    let npy = dir.join("s.npy");
    let csv = dir.join("s.csv");
    write_npy(&npy, &set).unwrap();
    write_csv(&csv, &set).unwrap();
    for (input, kind) in [(&npy, ".npy"), (&csv, "CSV")] {
        let whole = dir.join("whole.csv");
        let streamed = dir.join("streamed.csv");
        run(input, &whole, "never");
        let said = run(input, &streamed, "always");
        assert!(said.contains(&format!("streamed from {kind}")), "{said}");
        assert_eq!(
            std::fs::read(&whole).unwrap(),
            std::fs::read(&streamed).unwrap(),
            "{kind}: streamed output differs from the in-memory one"
        );
        std::fs::remove_file(&whole).unwrap();
        std::fs::remove_file(&streamed).unwrap();
    }
}

/// Ranges of rows of a CSV file with comments and blank lines equal the same rows of the
/// whole-file parse, for chunk sizes that cut the range anywhere; an error in a later range
/// names the file's own line and row.
#[test]
fn csv_ranges_are_the_rows_of_the_whole_parse() {
    let dir = scratch("stream-cli", "ranges");
    let mut text = String::from("# comment\nx,value\n");
    for i in 0..50 {
        if i % 7 == 3 {
            text.push_str("\n# a comment line\n");
        }
        text.push_str(&format!("{},{}\n", i as f64 / 50.0, (i * i) as f64));
    }
    let path = dir.join("r.csv");
    std::fs::write(&path, &text).unwrap();
    let whole = parse_csv(text.as_bytes(), &path).unwrap();
    let reader = SampleChunkReader::open(&path).unwrap();
    for (range, chunk) in [
        (0..50, 7),
        (3..17, 4),
        (13..14, 1),
        (40..80, 6),
        (49..50, 100),
    ] {
        let (mut xs, mut vs) = (Vec::new(), Vec::new());
        let mut firsts = Vec::new();
        reader
            .read_rows(
                range.clone(),
                chunk,
                SampleSet::default_names,
                |first, set| {
                    firsts.push(first);
                    xs.extend(set.positions);
                    vs.extend(set.values[0].iter().copied());
                    Ok::<(), IoError>(())
                },
            )
            .unwrap();
        let end = range.end.min(50);
        assert_eq!(xs, whole.positions[range.start..end], "{range:?} / {chunk}");
        assert_eq!(vs, whole.values[0][range.start..end], "{range:?} / {chunk}");
        assert_eq!(firsts[0], range.start);
    }
    let counted = SampleChunkReader::open(&path).unwrap().counted().unwrap();
    assert_eq!((counted.rows(), counted.value_channels()), (50, 1));
    assert_eq!(counted.bounds().unwrap(), (0.0, 49.0 / 50.0));

    // row 31 (0-based 30) broken: the error names its line in the file
    let broken = text.replacen(&format!("{},900", 30.0 / 50.0), "0.6,nine", 1);
    std::fs::write(&path, &broken).unwrap();
    let line = broken.lines().position(|l| l.ends_with("nine")).unwrap() + 1;
    let reader = SampleChunkReader::open(&path).unwrap();
    let err = reader
        .read_rows(20..40, 4, SampleSet::default_names, |_, _| {
            Ok::<(), IoError>(())
        })
        .unwrap_err();
    assert!(err.to_string().contains(&format!("line {line}")), "{err}");
}

/// An unsorted input streamed, and a method that does not stream: refused, naming the fix.
#[test]
fn streams_that_cannot_work_are_refused() {
    let dir = scratch("stream-cli", "refused");
    let mut set = sorted_samples(2_000);
    set.positions.swap(10, 1500);
    let csv = dir.join("unsorted.csv");
    write_csv(&csv, &set).unwrap();
    let out = dir.join("out.csv");
    let said = user_error(&args(&csv, &out, "always", &[]));
    assert!(said.contains("sort"), "{said}");
    assert!(!out.exists());
    let said = user_error(&args(&csv, &out, "always", &["--method", "local"]));
    assert!(said.contains("--method single"), "{said}");
}
