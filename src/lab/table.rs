//! The comparison tables of [`super::experiment::compare_methods`]: CSV rows, a Markdown PSNR
//! table and a Markdown time table (with the ratio of each method's time to the Gaussian
//! film filter's on the same samples).

use super::experiment::Comparison;
use crate::image::filters::FilmFilterKind;
use crate::image::ImageMethod;

/// Header of [`comparison_csv`].
pub const CSV_HEADER: &str = "scene,resolution,spp,sampler,noise,method,psnr,rmse,rel_mse,ssim,\
                              time_s,fit_s,pixels_s,time_over_gaussian,functions";

fn opt<T: ToString>(v: Option<T>) -> String {
    v.map_or(String::new(), |v| v.to_string())
}

/// CSV rows (no header) of comparisons: metrics, seconds by stage (`time_s` = fit + pixels),
/// the time over the Gaussian film filter's and the number of functions.
pub fn comparison_csv(comparisons: &[Comparison]) -> String {
    let mut out = String::new();
    for c in comparisons {
        for r in &c.results {
            out.push_str(&format!(
                "{},{},{},{},{},{},{:.4},{:.6},{:.6},{:.5},{:.4},{:.4},{:.4},{},{}\n",
                c.scene,
                c.sampling.plane,
                c.sampling.spp,
                c.sampling.sampler,
                c.sampling.noise,
                r.method,
                r.metrics.psnr,
                r.metrics.rmse,
                r.metrics.rel_mse,
                r.metrics.ssim,
                r.time_s.total,
                r.time_s.fit,
                r.time_s.pixels,
                opt(r.time_over_gaussian.map(|t| format!("{t:.2}"))),
                opt(r.functions),
            ));
        }
    }
    out
}

fn psnr_of(c: &Comparison, m: ImageMethod) -> Option<f64> {
    c.results
        .iter()
        .find(|r| r.method == m)
        .map(|r| r.metrics.psnr)
}

/// A Markdown table: one row per (scene, noise), one PSNR column per method (dB; the best in
/// bold), and the wavelet's margin over pbrt's default Gaussian filter.
pub fn comparison_markdown(comparisons: &[Comparison]) -> String {
    let Some(first) = comparisons.first() else {
        return String::new();
    };
    let methods: Vec<ImageMethod> = first.results.iter().map(|r| r.method).collect();
    let mut out = String::from("| scene | noise |");
    for m in &methods {
        out.push_str(&format!(" {m} |"));
    }
    out.push_str(" wavelet - gaussian |\n|---|---|");
    out.push_str(&"---:|".repeat(methods.len() + 1));
    out.push('\n');
    for c in comparisons {
        let best = c
            .results
            .iter()
            .map(|r| r.metrics.psnr)
            .fold(f64::NEG_INFINITY, f64::max);
        out.push_str(&format!("| {} | {} |", c.scene, c.sampling.noise));
        for r in &c.results {
            if r.metrics.psnr == best {
                out.push_str(&format!(" **{:.2}** |", r.metrics.psnr));
            } else {
                out.push_str(&format!(" {:.2} |", r.metrics.psnr));
            }
        }
        match (
            psnr_of(c, ImageMethod::Wavelet),
            psnr_of(c, ImageMethod::Film(FilmFilterKind::Gaussian)),
        ) {
            (Some(w), Some(g)) => out.push_str(&format!(" {:+.2} |\n", w - g)),
            _ => out.push_str(" |\n"),
        }
    }
    out
}

/// A Markdown table of seconds per method (fit + pixels, sampling and truth excluded), one row
/// per (scene, noise), and the ratio wavelet / Gaussian film filter on the same samples.
pub fn comparison_times_markdown(comparisons: &[Comparison]) -> String {
    let Some(first) = comparisons.first() else {
        return String::new();
    };
    let methods: Vec<ImageMethod> = first.results.iter().map(|r| r.method).collect();
    let mut out = String::from("| scene | noise |");
    for m in &methods {
        out.push_str(&format!(" {m} (s) |"));
    }
    out.push_str(" wavelet / gaussian |\n|---|---|");
    out.push_str(&"---:|".repeat(methods.len() + 1));
    out.push('\n');
    for c in comparisons {
        out.push_str(&format!("| {} | {} |", c.scene, c.sampling.noise));
        for r in &c.results {
            out.push_str(&format!(" {:.3} |", r.time_s.total));
        }
        let ratio = c
            .results
            .iter()
            .find(|r| r.method == ImageMethod::Wavelet)
            .and_then(|r| r.time_over_gaussian);
        out.push_str(&format!(" {} |\n", opt(ratio.map(|t| format!("{t:.1}")))));
    }
    out
}
