//! The streamed grid writer: `.npy` and CSV written block by block read back bit for bit.

mod common;

use rkwave::io::{read_csv, read_npy, GridWriter};

#[test]
fn grid_written_in_blocks_reads_back_exactly() {
    let dir = common::scratch("grid", "blocks");
    let rows = 1000;
    let xs: Vec<f64> = (0..rows).map(|i| i as f64 / (rows - 1) as f64).collect();
    let a: Vec<f64> = xs.iter().map(|x| (20.0 * x).sin() * 1e-7).collect();
    let b: Vec<f64> = xs.iter().map(|x| x.exp() * 6.02e23).collect();
    let names = vec!["a".to_string(), "b".to_string()];
    for file in ["grid.npy", "grid.csv"] {
        let path = dir.join(file);
        let mut w = GridWriter::create(&path, &names, rows).unwrap();
        for start in (0..rows).step_by(300) {
            let end = (start + 300).min(rows);
            let block = vec![a[start..end].to_vec(), b[start..end].to_vec()];
            w.write_block(&xs[start..end], &block).unwrap();
        }
        w.finish(false).unwrap();
        let back = if file.ends_with("npy") {
            read_npy(&path).unwrap()
        } else {
            read_csv(&path).unwrap()
        };
        assert_eq!(back.positions, xs, "{file}");
        assert_eq!(back.values, vec![a.clone(), b.clone()], "{file}");
    }
    // A non-finite value is an error naming its row, not a silent write.
    let path = dir.join("bad.csv");
    let mut w = GridWriter::create(&path, &names, 2).unwrap();
    let err = w
        .write_block(&[0.0, 1.0], &[vec![0.0, f64::NAN], vec![1.0, 2.0]])
        .unwrap_err();
    assert!(err.to_string().contains("row 2"), "{err}");
    // Abandoned on that error, the writer leaves nothing behind: no target, no temporary file.
    drop(w);
    let left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("bad"))
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
    // An existing target is never replaced without being asked, and stays as it was.
    let kept = dir.join("grid.csv");
    let before = std::fs::read(&kept).unwrap();
    let mut w = GridWriter::create(&kept, &names, 1).unwrap();
    w.write_block(&[0.5], &[vec![1.0], vec![2.0]]).unwrap();
    let refused = w.finish(false).unwrap_err();
    assert_eq!(
        refused.kind(),
        rkwave::error::ErrorKind::OutputRefused,
        "{refused}"
    );
    assert_eq!(std::fs::read(&kept).unwrap(), before);
}
