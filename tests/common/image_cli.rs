//! The image plane through the binary, shared by `tests/hardening_image.rs` and
//! `tests/hardening_image_sweep.rs`: sample files of a known scene, the argument vectors of
//! `reconstruct --dim 2` and `plan`, and a renderer answering a plan's positions.

use std::path::{Path, PathBuf};

use rkwave::io::{read_npy, write_npy, SampleSet};

use super::succeeds;

pub fn arg(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `n` image samples on `w x h` (positions by a fixed additive recurrence, a disc of value 1
/// on a ramp), `channels` equal channels, as `.npy` `n x (2 + channels)`.
pub fn samples_npy(path: &Path, w: usize, h: usize, n: usize, channels: usize) -> PathBuf {
    let xs: Vec<f64> = (0..n)
        .map(|i| w as f64 * (i as f64 * 0.754_877_666_2).fract())
        .collect();
    let ys: Vec<f64> = (0..n)
        .map(|i| h as f64 * (i as f64 * 0.569_840_290_9).fract())
        .collect();
    let v: Vec<f64> = xs
        .iter()
        .zip(&ys)
        .map(|(x, y)| {
            let (dx, dy) = (x - w as f64 / 3.0, y - h as f64 / 2.0);
            if dx * dx + dy * dy < (w as f64 / 4.0).powi(2) {
                1.0
            } else {
                0.2 + 0.5 * x / w as f64
            }
        })
        .collect();
    let mut values = vec![ys];
    values.extend(std::iter::repeat_n(v, channels));
    write_npy(path, &SampleSet::new(xs, values).unwrap()).unwrap();
    path.to_path_buf()
}

/// `reconstruct --dim 2` arguments on `w x h`.
pub fn reconstruct2d(input: &Path, output: &Path, resolution: &str) -> Vec<String> {
    [
        "reconstruct",
        "--dim",
        "2",
        "--input",
        arg(input),
        "--resolution",
        resolution,
        "--output",
        arg(output),
    ]
    .map(String::from)
    .to_vec()
}

/// `plan` continuing the plan in `state` with `samples`, the next positions to `out`.
pub fn plan_round(state: &Path, samples: &Path, out: &Path) -> Vec<String> {
    [
        "plan",
        "--state",
        arg(state),
        "--samples",
        arg(samples),
        "--out",
        arg(out),
    ]
    .map(String::from)
    .to_vec()
}

/// `plan` starting a plan at `resolution` and `spp` in `state`, the base positions to `out`.
pub fn plan_start(resolution: &str, spp: &str, state: &Path, out: &Path) -> Vec<String> {
    [
        "plan",
        "--resolution",
        resolution,
        "--spp",
        spp,
        "--state",
        arg(state),
        "--out",
        arg(out),
    ]
    .map(String::from)
    .to_vec()
}

/// The renderer of the plan loop: the positions of `next` (n x 2) with the value of the
/// disc scene appended to `previous` samples, written to `out`.
pub fn render(previous: Option<&Path>, next: &Path, out: &Path) {
    let pos = rkwave::io::read_npy(next).unwrap();
    let (mut xs, mut ys, mut vs) = match previous {
        Some(p) => {
            let s = rkwave::io::read_npy(p).unwrap();
            (
                s.positions.clone(),
                s.values[0].clone(),
                s.values[1].clone(),
            )
        }
        None => (Vec::new(), Vec::new(), Vec::new()),
    };
    for (x, y) in pos.positions.iter().zip(&pos.values[0]) {
        xs.push(*x);
        ys.push(*y);
        vs.push(if (x - 40.0).powi(2) + (y - 30.0).powi(2) < 400.0 {
            1.0
        } else {
            0.2
        });
    }
    write_npy(out, &SampleSet::new(xs, vec![ys, vs]).unwrap()).unwrap();
}

/// Starts a plan at `resolution`, `spp` in `dir`, renders its base and returns the samples.
pub fn started_plan(dir: &Path, resolution: &str, spp: &str) -> PathBuf {
    let n0 = dir.join("n0.npy");
    succeeds(&plan_start(resolution, spp, dir, &n0));
    let s0 = dir.join("s0.npy");
    render(None, &n0, &s0);
    s0
}

/// Runs a 24x20 plan at 4 spp in `dir` to its stop, the first call with `flags`, every round
/// asked to write `dir/final.npy` (`--final-image`); asserts that no image is written while the
/// plan continues and that the stopping call says it wrote it. Returns the last samples given
/// and the text of the stopping call.
pub fn plan_to_stop(dir: &Path, flags: &[&str]) -> (PathBuf, String) {
    let n0 = dir.join("n0.npy");
    let mut start = plan_start("24x20", "4", dir, &n0);
    start.extend(flags.iter().map(|f| f.to_string()));
    succeeds(&start);
    let fin = dir.join("final.npy");
    let (mut samples, mut next) = (None, n0);
    for k in 0.. {
        assert!(k < 64, "the plan stops");
        let s = dir.join(format!("s{k}.npy"));
        render(samples.as_deref(), &next, &s);
        let n = dir.join(format!("n{}.npy", k + 1));
        let mut args = plan_round(dir, &s, &n);
        args.extend(["--final-image".to_string(), arg(&fin).to_string()]);
        let text = succeeds(&args);
        samples = Some(s);
        next = n;
        if rkwave::io::read_npy(&next).is_err() || text.contains("stopped") {
            assert!(text.contains("wrote the final image"), "{text}");
            assert!(fin.exists(), "the stopping call writes the image");
            return (samples.unwrap(), text);
        }
        assert!(!fin.exists(), "no image while the plan continues");
    }
    unreachable!()
}

/// `.npy` bytes of `set` written by hand (the crate's writer refuses non-finite values).
pub fn write_npy_unchecked(path: &Path, set: &SampleSet) {
    let (m, k) = (set.len(), 1 + set.channels());
    let mut header = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': ({m}, {k}), }}");
    let unpadded = 10 + header.len() + 1;
    header.push_str(&" ".repeat((64 - unpadded % 64) % 64));
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    for i in 0..m {
        bytes.extend_from_slice(&set.positions[i].to_le_bytes());
        for c in &set.values {
            bytes.extend_from_slice(&c[i].to_le_bytes());
        }
    }
    std::fs::write(path, bytes).unwrap();
}

/// A renderer of the plan loop in a two-channel sample set: the positions of `next` (a plan's
/// positions file, `x, y`) appended to `set` with the values `y` and `scene(x, y)` (channels
/// `y`, `value`).
pub fn append_rendered(set: &mut SampleSet, next: &Path, scene: impl Fn(f64, f64) -> f64) {
    let positions = read_npy(next).unwrap();
    assert_eq!(positions.channels(), 1, "a positions file holds x and y");
    set.positions.extend(&positions.positions);
    if set.values.is_empty() {
        set.values = vec![vec![], vec![]];
    }
    set.values[0].extend(&positions.values[0]);
    for (&x, &y) in positions.positions.iter().zip(&positions.values[0]) {
        set.values[1].push(scene(x, y));
    }
    set.names = vec!["y".into(), "value".into()];
}

/// The pixel values of an `(H, W, C)` float64 `.npy` image: its last `n` 8-byte words.
pub fn npy_pixels(path: &Path, n: usize) -> Vec<f64> {
    let bytes = std::fs::read(path).unwrap();
    bytes[bytes.len() - 8 * n..]
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
        .collect()
}
