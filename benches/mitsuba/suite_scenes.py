"""The 16 scenes of the issue-38 suite, built from Mitsuba 3 plugins with `mi.load_dict`.

The split is FIXED before any tuning (see docs/measurements/suite.md): every parameter of
rkwave is chosen on `TUNING`; `VALIDATION` is only reported.

Tuning half:
* `direct`, `cornell`, `thinlens` -- the three scenes of `scenes.py`, unchanged.
* `stripes`  -- a tilted plane of fine high-contrast stripes (nearest-neighbour bitmap,
  period 2 texels) receding from the camera: several stripes a pixel over the far half of the
  image (texture past Nyquist); an area light, path traced (depth 3).
* `metal`    -- polished conductor spheres (alpha 0.01) and a rough one on a diffuse floor
  under a small, very bright area light (radiance 400): floor caustics found by BSDF
  sampling, i.e. fireflies; path traced (depth 6).
* `grid`     -- a fence of bars 1/3 to 1 pixel wide (world widths from the pixel footprint at
  the fence's depth) in front of a bright emitting backdrop; `direct` integrator.
* `rough`    -- rough conductors (alpha 0.15 / 0.3) and rough plastic under an area light,
  path traced (depth 4).
* `fog`      -- a box of homogeneous medium (sigma_t 0.6, albedo 0.9) containing a sphere and
  a cube, lit by an area light above it, `volpath` (depth 8).

Validation half:
* `grazing`  -- a ground plane with a fine random-tile texture seen at a grazing angle to the
  horizon, two objects on it; sun + sky, path traced (depth 3).
* `text`     -- rows of small glyphs (5 x 7 dot patterns, strokes ~0.5-1 pixel) on a plane;
  `direct` integrator with a point light: noise-free.
* `glass`    -- a dielectric sphere (eta 1.5) on a diffuse floor under a small area light:
  caustics and fireflies; path traced (depth 10).
* `envmap`   -- glossy and diffuse objects under a procedural HDR environment map (sky
  gradient, a sun spot of radiance ~200 over 2 x 2 texels); path traced (depth 4).
* `dof`      -- a thin lens (aperture 0.08, focus 4) on checker-textured objects at depths
  2.5 to 9; `direct` integrator with an area light.
* `wires`    -- cylinders 0.15 to 0.6 pixel thick across the view before a lit wall;
  path traced (depth 3).
* `medium`   -- a sphere of scattering medium (sigma_t 3, albedo 0.95) on a floor lit by a
  spot light; `volpath` (depth 8).
* `emitter`  -- a small visible spherical emitter (radiance 600) beside dark diffuse boxes
  and a dark floor; path traced (depth 4).

All procedural textures are numpy arrays turned into `mi.Bitmap` with fixed numpy seeds
(`TEXTURE_SEED`), so every scene is reproducible.
"""

import mitsuba as mi
import numpy as np

import scenes as base

TUNING = ("direct", "cornell", "thinlens", "stripes", "metal", "grid", "rough", "fog")
VALIDATION = ("grazing", "text", "glass", "envmap", "dof", "wires", "medium", "emitter")
SCENES = TUNING + VALIDATION
FILTERS = base.FILTERS
TEXTURE_SEED = 38
FOV = 40.0


def _rgb(v):
    return {"type": "rgb", "value": list(v)}


def _diffuse(v):
    return {"type": "diffuse", "reflectance": _rgb(v)}


def _bitmap(arr, to_uv=None, nearest=True):
    d = {"type": "bitmap", "bitmap": mi.Bitmap(np.ascontiguousarray(arr, dtype=np.float32)),
         "raw": True, "filter_type": "nearest" if nearest else "bilinear", "wrap_mode": "repeat"}
    if to_uv is not None:
        d["to_uv"] = to_uv
    return d


def _camera(w, h, rfilter, spp, origin, target, fov=FOV, lens=None):
    T = mi.ScalarTransform4f
    s = {"type": "perspective", "fov": fov,
         "to_world": T().look_at(origin=origin, target=target, up=[0, 1, 0])}
    if lens:
        s["type"] = "thinlens"
        s.update(lens)
    s["film"] = base._film(w, h, rfilter)
    s["sampler"] = base._sampler(spp)
    return s


def _floor(bsdf, size=20.0, y=0.0):
    T = mi.ScalarTransform4f
    return {"type": "rectangle", "bsdf": bsdf,
            "to_world": T().translate([0, y, 0]).rotate([1, 0, 0], -90).scale(size)}


def _area(center, size, radiance, facing_down=True):
    T = mi.ScalarTransform4f
    rot = T().rotate([1, 0, 0], 90) if facing_down else T()
    return {"type": "rectangle", "to_world": T().translate(center) @ rot @ T().scale(size),
            "emitter": {"type": "area", "radiance": _rgb(radiance)}}


def _stripes(w, h, rfilter, spp):
    T = mi.ScalarTransform4f
    # 1 x 2 texels: black, white -> period 2 texels; 400 periods over the plane's uv.
    tex = np.array([[[0.05] * 3, [0.9] * 3]], dtype=np.float32)
    plane = {"type": "rectangle",
             "to_world": T().translate([0, 0, -6]).rotate([0, 1, 0], 25).rotate([1, 0, 0], -90)
             @ T().scale([8.0, 8.0, 1.0]),
             "bsdf": {"type": "diffuse",
                      "reflectance": _bitmap(tex, T().rotate([0, 0, 1], 30).scale([300.0, 300.0, 1.0]))}}
    return {"type": "scene", "integrator": {"type": "path", "max_depth": 3},
            "sensor": _camera(w, h, rfilter, spp, [0, 1.2, 3], [0, 0, -4]),
            "plane": plane,
            "light": _area([1, 4, 0], 1.0, [12, 12, 12]),
            "sky": {"type": "constant", "radiance": _rgb([0.15, 0.15, 0.18])}}


def _metal(w, h, rfilter, spp):
    return {"type": "scene", "integrator": {"type": "path", "max_depth": 6},
            "sensor": _camera(w, h, rfilter, spp, [0, 1.6, 4.5], [0, 0.5, 0]),
            "floor": _floor(_diffuse([0.5, 0.5, 0.5])),
            "s1": {"type": "sphere", "center": [-0.8, 0.6, 0], "radius": 0.6,
                   "bsdf": {"type": "roughconductor", "material": "Au", "alpha": 0.01}},
            "s2": {"type": "sphere", "center": [0.7, 0.45, 0.6], "radius": 0.45,
                   "bsdf": {"type": "conductor", "material": "Ag"}},
            "s3": {"type": "sphere", "center": [0.6, 0.5, -1.0], "radius": 0.5,
                   "bsdf": {"type": "roughconductor", "material": "Cu", "alpha": 0.08}},
            "back": {"type": "rectangle", "bsdf": _diffuse([0.3, 0.3, 0.35]),
                     "to_world": mi.ScalarTransform4f().translate([0, 2, -3]).scale(6)},
            "light": _area([-0.5, 3.5, 1.0], 0.08, [400, 380, 350])}


def _grid(w, h, rfilter, spp):
    T = mi.ScalarTransform4f
    d = {"type": "scene", "integrator": {"type": "direct"},
         "sensor": _camera(w, h, rfilter, spp, [0, 0, 5], [0, 0, 0]),
         "backdrop": {"type": "rectangle", "to_world": T().translate([0, 0, -2]).scale(6),
                      "emitter": {"type": "area", "radiance": _rgb([0.9, 0.85, 0.8])}},
         "light": {"type": "point", "position": [1.5, 2.5, 5], "intensity": _rgb([15, 15, 15])}}
    px = 2 * 5 * np.tan(np.radians(FOV / 2)) / w  # world size of one pixel at the fence (z = 0)
    rng = np.random.default_rng(TEXTURE_SEED)
    for k, x in enumerate(np.linspace(-1.6, 1.6, 14)):
        width = px * rng.uniform(1 / 3, 1.0)
        d[f"v{k}"] = {"type": "cube", "bsdf": _diffuse([0.1, 0.12, 0.15]),
                      "to_world": T().translate([x, 0, 0]).rotate([0, 0, 1], 4).scale([width / 2, 1.5, 0.02])}
    for k, y in enumerate(np.linspace(-1.4, 1.4, 9)):
        width = px * rng.uniform(1 / 3, 1.0)
        d[f"h{k}"] = {"type": "cube", "bsdf": _diffuse([0.15, 0.1, 0.08]),
                      "to_world": T().translate([0, y, 0.05]).rotate([0, 0, 1], -3).scale([1.9, width / 2, 0.02])}
    return d


def _rough(w, h, rfilter, spp):
    return {"type": "scene", "integrator": {"type": "path", "max_depth": 4},
            "sensor": _camera(w, h, rfilter, spp, [0, 1.5, 4.5], [0, 0.5, 0]),
            "floor": _floor(_diffuse([0.4, 0.4, 0.4])),
            "back": {"type": "rectangle", "bsdf": _diffuse([0.5, 0.45, 0.4]),
                     "to_world": mi.ScalarTransform4f().translate([0, 2, -3]).scale(6)},
            "s1": {"type": "sphere", "center": [-1.0, 0.5, 0], "radius": 0.5,
                   "bsdf": {"type": "roughconductor", "material": "Al", "alpha": 0.15}},
            "s2": {"type": "sphere", "center": [0.1, 0.5, 0.3], "radius": 0.5,
                   "bsdf": {"type": "roughplastic", "diffuse_reflectance": _rgb([0.1, 0.3, 0.6]),
                            "alpha": 0.2}},
            "s3": {"type": "sphere", "center": [1.1, 0.5, -0.3], "radius": 0.5,
                   "bsdf": {"type": "roughconductor", "material": "Cu", "alpha": 0.3}},
            "light": _area([0.5, 3.0, 1.5], 0.5, [30, 30, 30])}


def _fog(w, h, rfilter, spp):
    T = mi.ScalarTransform4f
    medium = {"type": "homogeneous", "sigma_t": 0.6, "albedo": _rgb([0.9, 0.9, 0.9])}
    return {"type": "scene", "integrator": {"type": "volpath", "max_depth": 8},
            "sensor": _camera(w, h, rfilter, spp, [0, 1.5, 5.5], [0, 0.8, 0]),
            "floor": _floor(_diffuse([0.5, 0.5, 0.5])),
            "box": {"type": "cube", "bsdf": {"type": "null"}, "interior": medium,
                    "to_world": T().translate([0, 1.0, 0]).scale([2.0, 1.0, 1.5])},
            "sphere": {"type": "sphere", "center": [-0.6, 0.5, 0.2], "radius": 0.5,
                       "bsdf": _diffuse([0.7, 0.2, 0.2])},
            "cube": {"type": "cube", "bsdf": _diffuse([0.2, 0.5, 0.7]),
                     "to_world": T().translate([0.8, 0.4, -0.3]).rotate([0, 1, 0], 30).scale(0.4)},
            "light": _area([0, 3.0, 0], 0.6, [25, 24, 22])}


def _grazing(w, h, rfilter, spp):
    T = mi.ScalarTransform4f
    rng = np.random.default_rng(TEXTURE_SEED)
    tex = rng.uniform(0.05, 0.9, size=(64, 64, 1)).repeat(3, axis=2)
    tex *= np.array([1.0, 0.9, 0.75])
    ground = {"type": "rectangle", "to_world": T().rotate([1, 0, 0], -90).scale(100.0),
              "bsdf": {"type": "diffuse", "reflectance": _bitmap(tex, T().scale([60.0, 60.0, 1.0]))}}
    return {"type": "scene", "integrator": {"type": "path", "max_depth": 3},
            "sensor": _camera(w, h, rfilter, spp, [0, 0.35, 4], [0, 0.25, -10]),
            "ground": ground,
            "s": {"type": "sphere", "center": [-0.6, 0.3, 1.0], "radius": 0.3,
                  "bsdf": _diffuse([0.7, 0.3, 0.2])},
            "c": {"type": "cube", "bsdf": _diffuse([0.2, 0.4, 0.7]),
                  "to_world": T().translate([0.7, 0.25, -0.5]).rotate([0, 1, 0], 20).scale(0.25)},
            "sun": {"type": "directional", "direction": [-0.4, -0.5, -0.6],
                    "irradiance": _rgb([3.0, 2.9, 2.6])},
            "sky": {"type": "constant", "radiance": _rgb([0.25, 0.3, 0.4])}}


_GLYPHS = None


def _text_texture():
    """Rows of random 5 x 7 glyphs (dots set with probability 0.45), one texel per dot,
    1 texel between glyphs and 2 between rows, dark ink on light paper."""
    rng = np.random.default_rng(TEXTURE_SEED)
    cols, rows = 40, 14
    img = np.full((rows * 9, cols * 6), 0.85)
    for r in range(rows):
        for c in range(cols):
            g = rng.uniform(size=(7, 5)) < 0.45
            img[r * 9 + 1:r * 9 + 8, c * 6:c * 6 + 5][g] = 0.05
    return np.repeat(img[..., None], 3, axis=2)


def _text(w, h, rfilter, spp):
    T = mi.ScalarTransform4f
    tex = _text_texture()
    hh, ww = tex.shape[:2]
    plane = {"type": "rectangle",
             "to_world": T().translate([0, 0, 0]).rotate([0, 1, 0], 20).rotate([1, 0, 0], -15)
             @ T().scale([2.0, 2.0 * hh / ww, 1.0]),
             "bsdf": {"type": "diffuse", "reflectance": _bitmap(tex, nearest=True)}}
    return {"type": "scene", "integrator": {"type": "direct"},
            "sensor": _camera(w, h, rfilter, spp, [0, 0, 4.2], [0, 0, 0]),
            "plane": plane,
            "light": {"type": "point", "position": [-1.0, 1.5, 3.0], "intensity": _rgb([30, 30, 30])}}


def _glass(w, h, rfilter, spp):
    return {"type": "scene", "integrator": {"type": "path", "max_depth": 10},
            "sensor": _camera(w, h, rfilter, spp, [0, 2.0, 4.0], [0, 0.4, 0]),
            "floor": _floor(_diffuse([0.6, 0.6, 0.6])),
            "back": {"type": "rectangle", "bsdf": _diffuse([0.4, 0.4, 0.45]),
                     "to_world": mi.ScalarTransform4f().translate([0, 2, -2.5]).scale(6)},
            "ball": {"type": "sphere", "center": [0, 0.6, 0], "radius": 0.6,
                     "bsdf": {"type": "dielectric", "int_ior": 1.5, "ext_ior": 1.0}},
            "block": {"type": "cube", "bsdf": {"type": "dielectric", "int_ior": 1.5},
                      "to_world": mi.ScalarTransform4f().translate([1.2, 0.3, -0.4]).rotate([0, 1, 0], 25).scale(0.3)},
            "light": _area([-0.6, 3.0, -0.4], 0.15, [300, 290, 270])}


def _env_bitmap():
    """A 64 x 128 lat-long sky: a vertical gradient, a darker ground, and a sun of radiance
    200 over 2 x 2 texels."""
    hgt, wid = 64, 128
    v = (np.arange(hgt) + 0.5) / hgt
    sky = np.where(v[:, None] < 0.5, 0.3 + 0.9 * (0.5 - v[:, None]), 0.15) * np.ones((1, wid))
    img = np.stack([sky * 0.8, sky * 0.9, sky * 1.1], axis=2)
    img[18:20, 40:42] = [200.0, 190.0, 170.0]
    return img


def _envmap(w, h, rfilter, spp):
    T = mi.ScalarTransform4f
    return {"type": "scene", "integrator": {"type": "path", "max_depth": 4},
            "sensor": _camera(w, h, rfilter, spp, [0, 1.2, 4.5], [0, 0.5, 0]),
            "floor": _floor(_diffuse([0.5, 0.5, 0.5]), size=6.0),
            "s1": {"type": "sphere", "center": [-1.0, 0.5, 0], "radius": 0.5,
                   "bsdf": {"type": "roughconductor", "material": "Au", "alpha": 0.05}},
            "s2": {"type": "sphere", "center": [0.2, 0.5, 0.4], "radius": 0.5,
                   "bsdf": _diffuse([0.7, 0.7, 0.7])},
            "s3": {"type": "sphere", "center": [1.2, 0.5, -0.4], "radius": 0.5,
                   "bsdf": {"type": "roughplastic", "diffuse_reflectance": _rgb([0.6, 0.1, 0.1]),
                            "alpha": 0.1}},
            "env": {"type": "envmap", "bitmap": mi.Bitmap(_env_bitmap().astype(np.float32)),
                    "to_world": T().rotate([0, 1, 0], 30)}}


def _checker_tex(n, a, b):
    c = (np.indices((n, n)).sum(axis=0) % 2)[..., None]
    return np.where(c == 1, np.array(a), np.array(b))


def _dof(w, h, rfilter, spp):
    T = mi.ScalarTransform4f
    lens = {"aperture_radius": 0.08, "focus_distance": 4.0}
    d = {"type": "scene", "integrator": {"type": "direct"},
         "sensor": _camera(w, h, rfilter, spp, [0, 1.0, 5], [0, 0.6, 0], lens=lens),
         "floor": _floor({"type": "diffuse",
                          "reflectance": _bitmap(_checker_tex(2, [0.7, 0.7, 0.7], [0.15, 0.15, 0.15]),
                                                 T().scale([40.0, 40.0, 1.0]))}, size=20.0),
         "light": _area([2, 5, 4], 1.0, [20, 20, 20]),
         "sky": {"type": "constant", "radiance": _rgb([0.1, 0.1, 0.12])}}
    colours = ([0.8, 0.3, 0.2], [0.2, 0.7, 0.3], [0.2, 0.3, 0.8], [0.8, 0.7, 0.2])
    for k, (x, z) in enumerate(((-1.2, 2.5), (0.4, 1.0), (1.0, -1.5), (-0.8, -4.0))):
        tex = _checker_tex(8, colours[k], [0.9, 0.9, 0.9])
        d[f"o{k}"] = {"type": "cube", "to_world": T().translate([x, 0.45, z]).rotate([0, 1, 0], 35).scale(0.45),
                      "bsdf": {"type": "diffuse", "reflectance": _bitmap(tex)}}
    return d


def _wires(w, h, rfilter, spp):
    T = mi.ScalarTransform4f
    d = {"type": "scene", "integrator": {"type": "path", "max_depth": 3},
         "sensor": _camera(w, h, rfilter, spp, [0, 0, 5], [0, 0, 0]),
         "wall": {"type": "rectangle", "to_world": T().translate([0, 0, -1.5]).scale(5),
                  "bsdf": _diffuse([0.75, 0.7, 0.6])},
         "light": _area([0, 3.0, 2.5], 0.8, [15, 15, 15]),
         "sky": {"type": "constant", "radiance": _rgb([0.2, 0.2, 0.22])}}
    px = 2 * 5 * np.tan(np.radians(FOV / 2)) / w
    rng = np.random.default_rng(TEXTURE_SEED + 1)
    for k in range(12):
        radius = px * rng.uniform(0.15, 0.6) / 2
        y0, y1 = rng.uniform(-1.8, 1.8, size=2)
        d[f"w{k}"] = {"type": "cylinder", "p0": [-2.5, y0, 0.2 * k - 1.0], "p1": [2.5, y1, 0.2 * k - 1.0],
                      "radius": radius, "bsdf": _diffuse([0.05, 0.05, 0.05]) if k % 2 else
                      {"type": "conductor", "material": "Cu"}}
    return d


def _medium(w, h, rfilter, spp):
    T = mi.ScalarTransform4f
    medium = {"type": "homogeneous", "sigma_t": 3.0, "albedo": _rgb([0.95, 0.9, 0.8])}
    return {"type": "scene", "integrator": {"type": "volpath", "max_depth": 8},
            "sensor": _camera(w, h, rfilter, spp, [0, 1.3, 4.0], [0, 0.6, 0]),
            "floor": _floor(_diffuse([0.5, 0.5, 0.5])),
            "back": {"type": "rectangle", "bsdf": _diffuse([0.4, 0.4, 0.4]),
                     "to_world": T().translate([0, 2, -2.5]).scale(6)},
            "ball": {"type": "sphere", "center": [0, 0.7, 0], "radius": 0.7,
                     "bsdf": {"type": "null"}, "interior": medium},
            "spot": {"type": "spot", "cutoff_angle": 25.0, "intensity": _rgb([60, 60, 60]),
                     "to_world": T().look_at(origin=[1.5, 3.5, 2.0], target=[0, 0.5, 0], up=[0, 1, 0])},
            "sky": {"type": "constant", "radiance": _rgb([0.05, 0.05, 0.06])}}


def _emitter(w, h, rfilter, spp):
    T = mi.ScalarTransform4f
    return {"type": "scene", "integrator": {"type": "path", "max_depth": 4},
            "sensor": _camera(w, h, rfilter, spp, [0, 1.0, 4.0], [0, 0.6, 0]),
            "floor": _floor(_diffuse([0.08, 0.08, 0.08])),
            "back": {"type": "rectangle", "bsdf": _diffuse([0.05, 0.05, 0.06]),
                     "to_world": T().translate([0, 2, -2.0]).scale(6)},
            "b1": {"type": "cube", "bsdf": _diffuse([0.1, 0.08, 0.06]),
                   "to_world": T().translate([-0.5, 0.4, 0]).rotate([0, 1, 0], 20).scale(0.4)},
            "b2": {"type": "cube", "bsdf": _diffuse([0.06, 0.08, 0.1]),
                   "to_world": T().translate([0.7, 0.3, -0.6]).rotate([0, 1, 0], -15).scale(0.3)},
            "lamp": {"type": "sphere", "center": [0.15, 0.9, 0.3], "radius": 0.04,
                     "emitter": {"type": "area", "radiance": _rgb([600, 560, 500])}}}


_BUILDERS = {"stripes": _stripes, "metal": _metal, "grid": _grid, "rough": _rough, "fog": _fog,
             "grazing": _grazing, "text": _text, "glass": _glass, "envmap": _envmap, "dof": _dof,
             "wires": _wires, "medium": _medium, "emitter": _emitter}


def scene_dict(name, width, height, rfilter="box", spp=8):
    """The Mitsuba scene dict of `name` with the given film filter and sample count."""
    if name in base.SCENES:
        return base.scene_dict(name, width, height, rfilter, spp)
    if name not in _BUILDERS:
        raise ValueError(f"unknown scene {name!r}; expected one of {SCENES}")
    return _BUILDERS[name](width, height, rfilter, spp)


def load(name, width, height, rfilter="box", spp=8):
    """The loaded Mitsuba scene."""
    return mi.load_dict(scene_dict(name, width, height, rfilter, spp))


def aov_dict(name, width, height, spp):
    """The scene with Mitsuba's `aov` integrator: albedo and shading normal of the first hit
    (what OIDN takes as auxiliary images)."""
    d = scene_dict(name, width, height, "box", spp)
    d["integrator"] = {"type": "aov", "aovs": "albedo:albedo,nn:sh_normal"}
    return d
