//! Scenes: RGB radiance `L(u, v)` defined everywhere on the unit square, so a sampler may ask
//! for it at any point, read from JSON files (`data/scenes/*.json`).
//!
//! A scene on a `W x H` image plane is `L(x / W, y / H)` (`x, y` in pixels, `y` down). A scene
//! is a background colour and a list of layers painted in order: each layer covers part of
//! the square with a colour, and its `blend` says how it combines with what is below —
//! `over` (replace, the default), `add` or `multiply`. Layers (`"shape"`):
//!
//! | shape | fields | value |
//! | --- | --- | --- |
//! | `disk` | `center`, `radius`, `color` | `color` where `|p - c| <= radius` |
//! | `rect` | `center`, `size`, `angle_deg` (0), `color` | a rotated rectangle |
//! | `polygon` | `points`, `color` | even-odd fill of the closed polygon |
//! | `half_plane` | `point`, `normal_deg`, `color` | where `(p - point) . (cos a, sin a) >= 0` (a slanted edge) |
//! | `line` | `from`, `to`, `width`, `color` | points within `width / 2` of the segment |
//! | `zone_plate` | `center`, `k`, `color_a`, `color_b`, `radius` (none) | `b + (a - b) (1 + cos(pi k r^2)) / 2` |
//! | `linear_gradient` | `from`, `to`, `color_from`, `color_to` | linear ramp along `to - from`, clamped |
//! | `gaussian_blob` | `center`, `sigma`, `color` | `color exp(-r^2 / (2 sigma^2))` (with `blend: add`) |
//! | `shaded_sphere` | `center`, `radius`, `light`, `ambient` (0.05), `color` | Lambert shading of a sphere, `color (ambient + (1 - ambient) max(0, n . l))` |
//! | `glyphs` | `min`, `max`, `rows`, `cols`, `seed`, `color` | a grid of random 3 x 5 pixel-font glyphs (text-like detail) |
//! | `image` | `file`, `gain` (1) | a PNG over the square, sRGB-decoded to linear, bicubic (Catmull–Rom) between pixel centres |
//!
//! Points are `[u, v]`, colours `[r, g, b]` (linear). The zone plate's local frequency is
//! `k r` cycles per unit length, `k r / W` cycles per pixel: it passes Nyquist (1/2) at
//! `r = W / (2 k)`.
//!
//! Parsing is strict: an unknown shape, an unknown field, a missing one or a value of the wrong
//! kind is a [`SceneError`] naming the layer and the field.

use std::path::{Path, PathBuf};

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use serde::Serialize;
use serde_json::Value;
use thiserror::Error;

mod parse;

use parse::Parser;

/// An RGB triple (linear radiance).
pub type Rgb = [f64; 3];

/// Why a scene could not be read.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum SceneError {
    /// The file could not be read.
    #[error("cannot read scene file {path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The file is not JSON.
    #[error("scene file {path} is not valid JSON: {message}")]
    Json {
        /// The file.
        path: PathBuf,
        /// serde_json's message, with line and column.
        message: String,
    },
    /// A field is missing, unknown or has the wrong kind of value.
    #[error("scene file {path}: {place}: field `{field}` {problem}")]
    BadField {
        /// The file.
        path: PathBuf,
        /// Where: `scene` or `layers[i] (shape)`.
        place: String,
        /// The field at fault.
        field: String,
        /// What is wrong and what is expected.
        problem: String,
    },
    /// The `shape` of a layer is not one of the known shapes.
    #[error(
        "scene file {path}: layers[{index}]: unknown shape `{shape}`; expected one of {known}"
    )]
    UnknownShape {
        /// The file.
        path: PathBuf,
        /// The layer index.
        index: usize,
        /// The shape as given.
        shape: String,
        /// The known shapes.
        known: String,
    },
    /// An image layer's picture could not be loaded.
    #[error("scene file {path}: layers[{index}]: cannot load image {file}: {message}")]
    Image {
        /// The scene file.
        path: PathBuf,
        /// The layer index.
        index: usize,
        /// The picture.
        file: PathBuf,
        /// The cause (including "built without the `images` feature").
        message: String,
    },
}

/// How a layer combines with what lies below it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Blend {
    /// Replace.
    Over,
    /// Add.
    Add,
    /// Multiply channel by channel.
    Multiply,
}

/// A picture made continuous: Catmull–Rom bicubic interpolation between pixel centres.
#[derive(Debug, Clone)]
pub struct ImageField {
    width: usize,
    height: usize,
    /// Linear RGB, row-major.
    data: Vec<Rgb>,
}

impl ImageField {
    /// A field from linear RGB pixels (row-major, `width * height`).
    pub fn new(width: usize, height: usize, data: Vec<Rgb>) -> Self {
        assert_eq!(data.len(), width * height, "ImageField: data length");
        Self {
            width,
            height,
            data,
        }
    }

    /// The interpolated value at `(u, v)` in the unit square: pixel `(i, j)` has its centre at
    /// `((i + 1/2) / w, (j + 1/2) / h)`; indices outside are clamped to the border.
    pub fn eval(&self, u: f64, v: f64) -> Rgb {
        let (sx, sy) = (u * self.width as f64 - 0.5, v * self.height as f64 - 0.5);
        let (x0, y0) = (sx.floor(), sy.floor());
        let wx = catmull_rom(sx - x0);
        let wy = catmull_rom(sy - y0);
        let mut out = [0.0; 3];
        for (j, wyj) in wy.iter().enumerate() {
            let yy = (y0 as isize + j as isize - 1).clamp(0, self.height as isize - 1) as usize;
            for (i, wxi) in wx.iter().enumerate() {
                let xx = (x0 as isize + i as isize - 1).clamp(0, self.width as isize - 1) as usize;
                let p = self.data[yy * self.width + xx];
                let w = wxi * wyj;
                for (o, v) in out.iter_mut().zip(p) {
                    *o += w * v;
                }
            }
        }
        out
    }
}

/// Catmull–Rom weights of the taps at offsets -1, 0, 1, 2 for fractional position `t`
/// (Keys' cubic with `a = -1/2`; they sum to one and reproduce linear functions).
fn catmull_rom(t: f64) -> [f64; 4] {
    let t2 = t * t;
    let t3 = t2 * t;
    [
        0.5 * (-t3 + 2.0 * t2 - t),
        0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
        0.5 * (-3.0 * t3 + 4.0 * t2 + t),
        0.5 * (t3 - t2),
    ]
}

/// The sRGB transfer function decoded: 8-bit-encoded value in `[0, 1]` to linear.
pub fn srgb_to_linear(e: f64) -> f64 {
    if e <= 0.04045 {
        e / 12.92
    } else {
        ((e + 0.055) / 1.055).powf(2.4)
    }
}

/// The sRGB transfer function: linear in `[0, 1]` to encoded.
pub fn linear_to_srgb(l: f64) -> f64 {
    let l = l.clamp(0.0, 1.0);
    if l <= 0.003_130_8 {
        12.92 * l
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    }
}

#[derive(Debug, Clone)]
enum Geometry {
    Disk {
        c: [f64; 2],
        r: f64,
    },
    Rect {
        c: [f64; 2],
        half: [f64; 2],
        cos: f64,
        sin: f64,
    },
    Polygon {
        points: Vec<[f64; 2]>,
    },
    HalfPlane {
        p: [f64; 2],
        n: [f64; 2],
    },
    Line {
        a: [f64; 2],
        b: [f64; 2],
        half_width: f64,
    },
    ZonePlate {
        c: [f64; 2],
        k: f64,
        a: Rgb,
        b: Rgb,
        clip: Option<f64>,
    },
    Gradient {
        from: [f64; 2],
        to: [f64; 2],
        a: Rgb,
        b: Rgb,
    },
    Blob {
        c: [f64; 2],
        sigma: f64,
    },
    Sphere {
        c: [f64; 2],
        r: f64,
        light: [f64; 3],
        ambient: f64,
    },
    Glyphs {
        min: [f64; 2],
        max: [f64; 2],
        rows: usize,
        cols: usize,
        bits: Vec<u16>,
    },
    Image {
        field: ImageField,
        gain: f64,
    },
}

#[derive(Debug, Clone)]
struct Layer {
    geometry: Geometry,
    color: Rgb,
    blend: Blend,
}

const SHAPES: &str = "disk, rect, polygon, half_plane, line, zone_plate, linear_gradient, \
                      gaussian_blob, shaded_sphere, glyphs, image";

/// A scene read from JSON: see the module docs for the format.
#[derive(Debug, Clone)]
pub struct Scene {
    name: String,
    description: String,
    background: Rgb,
    layers: Vec<Layer>,
    fingerprint: u64,
}

fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

impl Layer {
    /// The layer's colour at `p`, or `None` where it does not cover.
    fn sample(&self, p: [f64; 2]) -> Option<Rgb> {
        let color = self.color;
        let scaled = |s: f64| Some([color[0] * s, color[1] * s, color[2] * s]);
        match &self.geometry {
            Geometry::Disk { c, r } => {
                let d = sub(p, *c);
                (dot(d, d) <= r * r).then_some(color)
            }
            Geometry::Rect { c, half, cos, sin } => {
                let d = sub(p, *c);
                let (lu, lv) = (cos * d[0] + sin * d[1], -sin * d[0] + cos * d[1]);
                (lu.abs() <= half[0] && lv.abs() <= half[1]).then_some(color)
            }
            Geometry::Polygon { points } => {
                let mut inside = false;
                let n = points.len();
                for i in 0..n {
                    let (a, b) = (points[i], points[(i + n - 1) % n]);
                    if (a[1] > p[1]) != (b[1] > p[1])
                        && p[0] < (b[0] - a[0]) * (p[1] - a[1]) / (b[1] - a[1]) + a[0]
                    {
                        inside = !inside;
                    }
                }
                inside.then_some(color)
            }
            Geometry::HalfPlane { p: q, n } => (dot(sub(p, *q), *n) >= 0.0).then_some(color),
            Geometry::Line { a, b, half_width } => {
                let ab = sub(*b, *a);
                let t = (dot(sub(p, *a), ab) / dot(ab, ab)).clamp(0.0, 1.0);
                let d = sub(p, [a[0] + t * ab[0], a[1] + t * ab[1]]);
                (dot(d, d) <= half_width * half_width).then_some(color)
            }
            Geometry::ZonePlate { c, k, a, b, clip } => {
                let d = sub(p, *c);
                let r2 = dot(d, d);
                if clip.is_some_and(|r| r2 > r * r) {
                    return None;
                }
                let s = 0.5 * (1.0 + (std::f64::consts::PI * k * r2).cos());
                Some([0, 1, 2].map(|i| b[i] + (a[i] - b[i]) * s))
            }
            Geometry::Gradient { from, to, a, b } => {
                let d = sub(*to, *from);
                let t = (dot(sub(p, *from), d) / dot(d, d)).clamp(0.0, 1.0);
                Some([0, 1, 2].map(|i| a[i] + (b[i] - a[i]) * t))
            }
            Geometry::Blob { c, sigma } => {
                let d = sub(p, *c);
                scaled((-dot(d, d) / (2.0 * sigma * sigma)).exp())
            }
            Geometry::Sphere {
                c,
                r,
                light,
                ambient,
            } => {
                let d = sub(p, *c);
                let q = dot(d, d) / (r * r);
                if q > 1.0 {
                    return None;
                }
                // Unit normal of the sphere seen from the viewer (z towards the viewer).
                let n = [d[0] / r, d[1] / r, (1.0 - q).sqrt()];
                let lambert = (n[0] * light[0] + n[1] * light[1] + n[2] * light[2]).max(0.0);
                scaled(ambient + (1.0 - ambient) * lambert)
            }
            Geometry::Glyphs {
                min,
                max,
                rows,
                cols,
                bits,
            } => {
                if p[0] < min[0] || p[1] < min[1] || p[0] >= max[0] || p[1] >= max[1] {
                    return None;
                }
                // Each glyph cell is 4 x 6 font pixels: 3 x 5 glyph, one column and row gap.
                let gu = (p[0] - min[0]) / (max[0] - min[0]) * (*cols * 4) as f64;
                let gv = (p[1] - min[1]) / (max[1] - min[1]) * (*rows * 6) as f64;
                let (cu, cv) = (gu as usize, gv as usize);
                let (gi, gj) = (cu / 4, cv / 6);
                let (fx, fy) = (cu % 4, cv % 6);
                if gi >= *cols || gj >= *rows || fx == 3 || fy == 5 {
                    return None;
                }
                let glyph = bits[gj * cols + gi];
                ((glyph >> (fy * 3 + fx)) & 1 == 1).then_some(color)
            }
            Geometry::Image { field, gain } => {
                let v = field.eval(p[0], p[1]);
                Some(v.map(|x| x * gain))
            }
        }
    }
}

impl Scene {
    /// The folder of the built-in scenes, `data/scenes` in the crate.
    pub fn builtin_dir() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("data")
            .join("scenes")
    }

    /// The built-in scene files, sorted by name.
    pub fn builtin_files() -> Result<Vec<PathBuf>, SceneError> {
        let dir = Self::builtin_dir();
        let entries = std::fs::read_dir(&dir).map_err(|source| SceneError::Read {
            path: dir.clone(),
            source,
        })?;
        let mut files: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "json"))
            .collect();
        files.sort();
        Ok(files)
    }

    /// Reads a scene file (image layers are resolved relative to its folder).
    pub fn from_file(path: impl AsRef<Path>) -> Result<Self, SceneError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_json(&text, path)
    }

    /// Parses a scene from JSON text; `path` names it in errors and anchors relative image
    /// files.
    pub fn from_json(text: &str, path: &Path) -> Result<Self, SceneError> {
        let value: Value = serde_json::from_str(text).map_err(|e| SceneError::Json {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        let mut p = Parser {
            path,
            place: "scene".to_string(),
        };
        let top = p.object(&value, "scene")?;
        p.allow(top, &["name", "description", "background", "layers"])?;
        let name = p.string(top, "name")?;
        let description = match top.get("description") {
            Some(_) => p.string(top, "description")?,
            None => String::new(),
        };
        let background = p.color_or(top, "background", [0.0; 3])?;
        let layers_value = top
            .get("layers")
            .ok_or_else(|| p.bad("layers", "is missing"))?;
        let list = layers_value
            .as_array()
            .ok_or_else(|| p.bad("layers", "must be a list of layer objects"))?;
        let mut layers = Vec::with_capacity(list.len());
        for (index, lv) in list.iter().enumerate() {
            layers.push(p.layer(index, lv)?);
        }
        Ok(Self {
            name,
            description,
            background,
            layers,
            fingerprint: fnv1a(text.as_bytes()),
        })
    }

    /// The scene's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The scene's one-line description.
    pub fn description(&self) -> &str {
        &self.description
    }

    /// A 64-bit FNV-1a hash of the scene's JSON text (keys the ground-truth cache).
    pub fn fingerprint(&self) -> u64 {
        self.fingerprint
    }

    /// `L(u, v)` on the unit square.
    pub fn radiance(&self, u: f64, v: f64) -> Rgb {
        let mut acc = self.background;
        for layer in &self.layers {
            if let Some(c) = layer.sample([u, v]) {
                match layer.blend {
                    Blend::Over => acc = c,
                    Blend::Add => (0..3).for_each(|i| acc[i] += c[i]),
                    Blend::Multiply => (0..3).for_each(|i| acc[i] *= c[i]),
                }
            }
        }
        acc
    }

    /// `L(x / W, y / H)` at a point `(x, y)` of a `W x H` image plane.
    pub fn radiance_on(&self, plane: super::ImagePlane, x: f64, y: f64) -> Rgb {
        self.radiance(x / plane.width() as f64, y / plane.height() as f64)
    }
}

/// 64-bit FNV-1a.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

impl SceneError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            SceneError::Read { .. } | SceneError::Image { .. } => {
                crate::error::ErrorKind::Unreadable
            }
            SceneError::Json { .. }
            | SceneError::BadField { .. }
            | SceneError::UnknownShape { .. } => crate::error::ErrorKind::InvalidInput,
        }
    }
}

crate::error::classified!(SceneError);

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Scene, SceneError> {
        Scene::from_json(text, Path::new("test.json"))
    }

    #[test]
    fn bad_scenes_name_the_field() {
        let e = parse(r#"{"name":"a","layers":[{"shape":"star","center":[0,0]}]}"#).unwrap_err();
        assert!(e.to_string().contains("unknown shape `star`"), "{e}");
        let e = parse(r#"{"name":"a","layers":[{"shape":"disk","center":[0,0],"radius":-1,"color":[1,1,1]}]}"#)
            .unwrap_err();
        assert!(e.to_string().contains("`radius` must be positive"), "{e}");
        let e = parse(
            r#"{"name":"a","layers":[{"shape":"disk","center":[0],"radius":1,"color":[1,1,1]}]}"#,
        )
        .unwrap_err();
        assert!(
            e.to_string().contains("layers[0] (disk): field `center`"),
            "{e}"
        );
        let e = parse(
            r#"{"name":"a","layers":[{"shape":"disk","centre":[0,0],"radius":1,"color":[1,1,1]}]}"#,
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .contains("field `centre` is not a known field"),
            "{e}"
        );
        let e = parse(r#"{"name":"a","layers":[]"#).unwrap_err();
        assert!(matches!(e, SceneError::Json { .. }));
        let e = parse(r#"{"layers":[]}"#).unwrap_err();
        assert!(e.to_string().contains("field `name` is missing"), "{e}");
    }

    #[test]
    fn layers_paint_in_order() {
        let s = parse(
            r#"{"name":"t","background":[0.1,0.2,0.3],"layers":[
              {"shape":"half_plane","point":[0.5,0],"normal_deg":0,"color":[1,1,1]},
              {"shape":"disk","center":[0.75,0.5],"radius":0.1,"color":[0,0,1]},
              {"shape":"gaussian_blob","center":[0.25,0.5],"sigma":0.1,"color":[1,0,0],"blend":"add"},
              {"shape":"polygon","points":[[0,0],[0.2,0],[0,0.2]],"color":[0,1,0]}
            ]}"#,
        )
        .unwrap();
        // The blob (added after the disk) reaches everywhere: exp(-|p - c|^2 / (2 sigma^2)).
        let tail = |u: f64, v: f64| {
            (-((u - 0.25f64).powi(2) + (v - 0.5f64).powi(2)) / (2.0 * 0.1 * 0.1)).exp()
        };
        let close = |a: [f64; 3], b: [f64; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-15);
        assert!(close(s.radiance(0.75, 0.5), [tail(0.75, 0.5), 0.0, 1.0]));
        assert!(close(
            s.radiance(0.9, 0.9),
            [1.0 + tail(0.9, 0.9), 1.0, 1.0]
        ));
        assert_eq!(s.radiance(0.05, 0.05), [0.0, 1.0, 0.0]);
        let blob = s.radiance(0.25, 0.6);
        assert!((blob[0] - (0.1 + (-0.5f64).exp())).abs() < 1e-15);
        assert_eq!(blob[1], 0.2);
    }

    #[test]
    fn bicubic_interpolates_pixel_centres_and_linear_ramps() {
        // A linear ramp in x: Catmull-Rom reproduces it between interior centres exactly.
        let data = (0..4 * 6).map(|i| [(i % 6) as f64; 3]).collect();
        let f = ImageField::new(6, 4, data);
        assert!((f.eval(2.5 / 6.0, 0.4)[0] - 2.0).abs() < 1e-12);
        assert!((f.eval(2.8 / 6.0, 0.6)[1] - 2.3).abs() < 1e-12);
        assert!((srgb_to_linear(linear_to_srgb(0.3)) - 0.3).abs() < 1e-12);
    }

    #[test]
    fn builtin_scenes_parse() {
        let files = Scene::builtin_files().unwrap();
        assert!(files.len() >= 7, "{files:?}");
        for f in files {
            let s = Scene::from_file(&f).unwrap_or_else(|e| panic!("{e}"));
            let v = s.radiance(0.37, 0.61);
            assert!(v.iter().all(|x| x.is_finite()), "{}", s.name());
        }
    }
}
