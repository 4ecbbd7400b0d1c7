//! Writes a large image-plane sample file for the tiled fit's scale measurements, row by
//! row (never held whole): `W x H` pixels, `SPP` stratified samples per pixel (a jittered
//! `s x s` grid, `SPP = s^2`), the RGB radiance of a built-in scene plus Gaussian noise of
//! standard deviation `NOISE`, as a `.npy` of `m x 5` float64 (`x, y, r, g, b`).
//!
//! `cargo run --release --example tile_samples -- W H SPP NOISE OUT.npy [SCENE]`

use std::io::{BufWriter, Write};

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rkwave::image::scene::Scene;
use rkwave::image::ImagePlane;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 5 {
        return Err("usage: tile_samples W H SPP NOISE OUT.npy [SCENE]".into());
    }
    let (w, h): (usize, usize) = (args[0].parse()?, args[1].parse()?);
    let spp: usize = args[2].parse()?;
    let noise: f64 = args[3].parse()?;
    let s = (spp as f64).sqrt().round() as usize;
    if s * s != spp {
        return Err(format!("SPP {spp} is not a square (stratified s x s per pixel)").into());
    }
    let scene_name = args.get(5).map_or("shapes", String::as_str);
    let scene = Scene::from_file(Scene::builtin_dir().join(format!("{scene_name}.json")))?;
    let plane = ImagePlane::new(w, h)?;
    let m = w * h * spp;
    let mut header = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': ({m}, 5), }}");
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut out = BufWriter::with_capacity(1 << 22, std::fs::File::create(&args[4])?);
    out.write_all(b"\x93NUMPY\x01\x00")?;
    out.write_all(&(header.len() as u16).to_le_bytes())?;
    out.write_all(header.as_bytes())?;
    let mut rng = Pcg64::seed_from_u64(7);
    let normal = |rng: &mut Pcg64| {
        let u1: f64 = 1.0 - rng.random::<f64>();
        let u2: f64 = rng.random();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    };
    for py in 0..h {
        for px in 0..w {
            for j in 0..s {
                for i in 0..s {
                    let x = px as f64 + (i as f64 + rng.random::<f64>()) / s as f64;
                    let y = py as f64 + (j as f64 + rng.random::<f64>()) / s as f64;
                    let rgb = scene.radiance_on(plane, x, y);
                    out.write_all(&x.to_le_bytes())?;
                    out.write_all(&y.to_le_bytes())?;
                    for v in rgb {
                        out.write_all(&(v + noise * normal(&mut rng)).to_le_bytes())?;
                    }
                }
            }
        }
    }
    out.flush()?;
    eprintln!("wrote {m} samples to {}", args[4]);
    Ok(())
}
