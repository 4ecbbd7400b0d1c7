//! The scene file reader: a strict JSON field reader whose every error names the place and
//! the field (split from the scene model in `mod.rs`), and the loader of image-backed layers.

use std::path::Path;

use serde_json::{Map, Value};

use super::*;

/// Strict field reader: every error names the place and the field.
pub(super) struct Parser<'a> {
    pub(super) path: &'a Path,
    pub(super) place: String,
}

impl Parser<'_> {
    pub(super) fn bad(&self, field: &str, problem: impl Into<String>) -> SceneError {
        SceneError::BadField {
            path: self.path.to_path_buf(),
            place: self.place.clone(),
            field: field.to_string(),
            problem: problem.into(),
        }
    }

    pub(super) fn object<'v>(
        &self,
        v: &'v Value,
        what: &str,
    ) -> Result<&'v Map<String, Value>, SceneError> {
        v.as_object()
            .ok_or_else(|| self.bad(what, "must be a JSON object `{...}`"))
    }

    pub(super) fn allow(&self, obj: &Map<String, Value>, known: &[&str]) -> Result<(), SceneError> {
        for key in obj.keys() {
            if !known.contains(&key.as_str()) {
                return Err(self.bad(
                    key,
                    format!(
                        "is not a known field here; expected one of {}",
                        known.join(", ")
                    ),
                ));
            }
        }
        Ok(())
    }

    pub(super) fn get<'v>(
        &self,
        obj: &'v Map<String, Value>,
        field: &str,
    ) -> Result<&'v Value, SceneError> {
        obj.get(field).ok_or_else(|| self.bad(field, "is missing"))
    }

    pub(super) fn string(
        &self,
        obj: &Map<String, Value>,
        field: &str,
    ) -> Result<String, SceneError> {
        self.get(obj, field)?
            .as_str()
            .map(str::to_string)
            .ok_or_else(|| self.bad(field, "must be a string"))
    }

    pub(super) fn number(&self, obj: &Map<String, Value>, field: &str) -> Result<f64, SceneError> {
        let v = self.get(obj, field)?;
        v.as_f64()
            .filter(|x| x.is_finite())
            .ok_or_else(|| self.bad(field, format!("must be a finite number, found {v}")))
    }

    pub(super) fn positive(
        &self,
        obj: &Map<String, Value>,
        field: &str,
    ) -> Result<f64, SceneError> {
        let x = self.number(obj, field)?;
        if x > 0.0 {
            Ok(x)
        } else {
            Err(self.bad(field, format!("must be positive, found {x}")))
        }
    }

    pub(super) fn count(
        &self,
        obj: &Map<String, Value>,
        field: &str,
        max: u64,
    ) -> Result<usize, SceneError> {
        let v = self.get(obj, field)?;
        match v.as_u64() {
            Some(n) if (1..=max).contains(&n) => Ok(n as usize),
            _ => Err(self.bad(field, format!("must be an integer in 1..={max}, found {v}"))),
        }
    }

    pub(super) fn numbers<const N: usize>(
        &self,
        v: &Value,
        field: &str,
    ) -> Result<[f64; N], SceneError> {
        let err = || {
            self.bad(
                field,
                format!("must be a list of {N} finite numbers, found {v}"),
            )
        };
        let list = v.as_array().ok_or_else(err)?;
        if list.len() != N {
            return Err(err());
        }
        let mut out = [0.0; N];
        for (o, x) in out.iter_mut().zip(list) {
            *o = x.as_f64().filter(|x| x.is_finite()).ok_or_else(err)?;
        }
        Ok(out)
    }

    pub(super) fn point(
        &self,
        obj: &Map<String, Value>,
        field: &str,
    ) -> Result<[f64; 2], SceneError> {
        self.numbers::<2>(self.get(obj, field)?, field)
    }

    pub(super) fn color(&self, obj: &Map<String, Value>, field: &str) -> Result<Rgb, SceneError> {
        self.numbers::<3>(self.get(obj, field)?, field)
    }

    pub(super) fn color_or(
        &self,
        obj: &Map<String, Value>,
        field: &str,
        d: Rgb,
    ) -> Result<Rgb, SceneError> {
        match obj.get(field) {
            Some(v) => self.numbers::<3>(v, field),
            None => Ok(d),
        }
    }

    pub(super) fn number_or(
        &self,
        obj: &Map<String, Value>,
        field: &str,
        d: f64,
    ) -> Result<f64, SceneError> {
        match obj.get(field) {
            Some(_) => self.number(obj, field),
            None => Ok(d),
        }
    }

    pub(super) fn layer(&mut self, index: usize, v: &Value) -> Result<Layer, SceneError> {
        self.place = format!("layers[{index}]");
        let obj = self.object(v, "layer")?;
        let shape = self.string(obj, "shape")?;
        self.place = format!("layers[{index}] ({shape})");
        let fields: &[&str] = match shape.as_str() {
            "disk" => &["center", "radius", "color"],
            "rect" => &["center", "size", "angle_deg", "color"],
            "polygon" => &["points", "color"],
            "half_plane" => &["point", "normal_deg", "color"],
            "line" => &["from", "to", "width", "color"],
            "zone_plate" => &["center", "k", "color_a", "color_b", "radius"],
            "linear_gradient" => &["from", "to", "color_from", "color_to"],
            "gaussian_blob" => &["center", "sigma", "color"],
            "shaded_sphere" => &["center", "radius", "light", "ambient", "color"],
            "glyphs" => &["min", "max", "rows", "cols", "seed", "color"],
            "image" => &["file", "gain"],
            _ => {
                return Err(SceneError::UnknownShape {
                    path: self.path.to_path_buf(),
                    index,
                    shape,
                    known: SHAPES.to_string(),
                })
            }
        };
        let mut known = vec!["shape", "blend"];
        known.extend_from_slice(fields);
        self.allow(obj, &known)?;
        let blend = match obj.get("blend").map(|b| b.as_str()) {
            None => Blend::Over,
            Some(Some("over")) => Blend::Over,
            Some(Some("add")) => Blend::Add,
            Some(Some("multiply")) => Blend::Multiply,
            Some(_) => {
                return Err(self.bad("blend", "must be one of \"over\", \"add\", \"multiply\""))
            }
        };
        let color = if fields.contains(&"color") {
            self.color(obj, "color")?
        } else {
            [1.0; 3]
        };
        let geometry = match shape.as_str() {
            "disk" => Geometry::Disk {
                c: self.point(obj, "center")?,
                r: self.positive(obj, "radius")?,
            },
            "rect" => {
                let size = self.point(obj, "size")?;
                if size.iter().any(|s| *s <= 0.0) {
                    return Err(self.bad(
                        "size",
                        format!("must be two positive numbers, found {size:?}"),
                    ));
                }
                let a = self.number_or(obj, "angle_deg", 0.0)?.to_radians();
                Geometry::Rect {
                    c: self.point(obj, "center")?,
                    half: [size[0] / 2.0, size[1] / 2.0],
                    cos: a.cos(),
                    sin: a.sin(),
                }
            }
            "polygon" => {
                let list = self.get(obj, "points")?;
                let items = list.as_array().filter(|l| l.len() >= 3).ok_or_else(|| {
                    self.bad("points", "must be a list of at least 3 points [u, v]")
                })?;
                let points = items
                    .iter()
                    .map(|q| self.numbers::<2>(q, "points"))
                    .collect::<Result<Vec<_>, _>>()?;
                Geometry::Polygon { points }
            }
            "half_plane" => {
                let a = self.number(obj, "normal_deg")?.to_radians();
                Geometry::HalfPlane {
                    p: self.point(obj, "point")?,
                    n: [a.cos(), a.sin()],
                }
            }
            "line" => {
                let (a, b) = (self.point(obj, "from")?, self.point(obj, "to")?);
                if a == b {
                    return Err(self.bad("to", "must differ from `from`"));
                }
                Geometry::Line {
                    a,
                    b,
                    half_width: self.positive(obj, "width")? / 2.0,
                }
            }
            "zone_plate" => Geometry::ZonePlate {
                c: self.point(obj, "center")?,
                k: self.positive(obj, "k")?,
                a: self.color(obj, "color_a")?,
                b: self.color(obj, "color_b")?,
                clip: match obj.get("radius") {
                    Some(_) => Some(self.positive(obj, "radius")?),
                    None => None,
                },
            },
            "linear_gradient" => {
                let (from, to) = (self.point(obj, "from")?, self.point(obj, "to")?);
                if from == to {
                    return Err(self.bad("to", "must differ from `from`"));
                }
                Geometry::Gradient {
                    from,
                    to,
                    a: self.color(obj, "color_from")?,
                    b: self.color(obj, "color_to")?,
                }
            }
            "gaussian_blob" => Geometry::Blob {
                c: self.point(obj, "center")?,
                sigma: self.positive(obj, "sigma")?,
            },
            "shaded_sphere" => {
                let l = self.numbers::<3>(self.get(obj, "light")?, "light")?;
                let norm = (l[0] * l[0] + l[1] * l[1] + l[2] * l[2]).sqrt();
                if norm == 0.0 {
                    return Err(self.bad("light", "must be a nonzero direction [x, y, z]"));
                }
                let ambient = self.number_or(obj, "ambient", 0.05)?;
                if !(0.0..=1.0).contains(&ambient) {
                    return Err(self.bad("ambient", format!("must lie in [0, 1], found {ambient}")));
                }
                Geometry::Sphere {
                    c: self.point(obj, "center")?,
                    r: self.positive(obj, "radius")?,
                    light: l.map(|x| x / norm),
                    ambient,
                }
            }
            "glyphs" => {
                let (min, max) = (self.point(obj, "min")?, self.point(obj, "max")?);
                if max[0] <= min[0] || max[1] <= min[1] {
                    return Err(self.bad("max", "must exceed `min` in both coordinates"));
                }
                let rows = self.count(obj, "rows", 1000)?;
                let cols = self.count(obj, "cols", 1000)?;
                let seed = self
                    .get(obj, "seed")?
                    .as_u64()
                    .ok_or_else(|| self.bad("seed", "must be a non-negative integer"))?;
                let mut rng = Pcg64::seed_from_u64(seed);
                // 15 random bits per glyph, about half of them set (the density of text).
                let bits = (0..rows * cols)
                    .map(|_| rng.random::<u16>() & 0x7fff)
                    .collect();
                Geometry::Glyphs {
                    min,
                    max,
                    rows,
                    cols,
                    bits,
                }
            }
            "image" => {
                let file = self.string(obj, "file")?;
                let full = self.path.parent().unwrap_or(Path::new(".")).join(&file);
                let field = load_image_field(&full).map_err(|message| SceneError::Image {
                    path: self.path.to_path_buf(),
                    index,
                    file: full.clone(),
                    message,
                })?;
                Geometry::Image {
                    field,
                    gain: self.number_or(obj, "gain", 1.0)?,
                }
            }
            _ => unreachable!("shape list checked above"),
        };
        Ok(Layer {
            geometry,
            color,
            blend,
        })
    }
}

/// Loads a picture as linear RGB (sRGB-decoded from 8 bits; 32-bit float files as they are).
#[cfg(feature = "images")]
pub(super) fn load_image_field(path: &Path) -> Result<ImageField, String> {
    let img = image::open(path).map_err(|e| e.to_string())?;
    let float = matches!(
        img,
        image::DynamicImage::ImageRgb32F(_) | image::DynamicImage::ImageRgba32F(_)
    );
    let rgb = img.into_rgb32f();
    let (w, h) = rgb.dimensions();
    let data = rgb
        .pixels()
        .map(|p| {
            p.0.map(|c| {
                if float {
                    c as f64
                } else {
                    srgb_to_linear(c as f64)
                }
            })
        })
        .collect();
    Ok(ImageField::new(w as usize, h as usize, data))
}

#[cfg(not(feature = "images"))]
pub(super) fn load_image_field(_path: &Path) -> Result<ImageField, String> {
    Err("rkwave was built without the `images` feature; rebuild with `--features images`".into())
}
