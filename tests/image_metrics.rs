//! SSIM and PSNR against scikit-image on a stored fixture (`data/fixtures/ssim_fixture.json`,
//! made by `data/fixtures/ssim_fixture.py` with scikit-image 0.26.0).

use rkwave::image::metrics::{compare, ssim_channel};
use rkwave::image::{ImagePlane, PixelImage};

#[derive(serde::Deserialize)]
struct Fixture {
    width: usize,
    height: usize,
    reference: Vec<Vec<f64>>,
    image: Vec<Vec<f64>>,
    ssim_per_channel: Vec<f64>,
    ssim: f64,
    psnr: f64,
}

#[test]
fn ssim_and_psnr_match_scikit_image() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/data/fixtures/ssim_fixture.json"
    );
    let f: Fixture = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let plane = ImagePlane::new(f.width, f.height).unwrap();
    // Same arithmetic (separable Gaussian of 11 taps, mirrored borders, cropped mean) in a
    // different order of summation: agreement to ~1e-15 per value, so 1e-12 on the mean.
    for c in 0..3 {
        let s = ssim_channel(&f.image[c], &f.reference[c], f.width, f.height);
        assert!(
            (s - f.ssim_per_channel[c]).abs() < 1e-12,
            "channel {c}: {s} against scikit-image {}",
            f.ssim_per_channel[c]
        );
    }
    let img = PixelImage {
        plane,
        channels: f.image,
    };
    let reference = PixelImage {
        plane,
        channels: f.reference,
    };
    let m = compare(&img, &reference);
    assert!((m.ssim - f.ssim).abs() < 1e-12, "{} {}", m.ssim, f.ssim);
    assert!((m.psnr - f.psnr).abs() < 1e-10, "{} {}", m.psnr, f.psnr);
}
