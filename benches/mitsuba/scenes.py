"""The three scenes, built from Mitsuba 3 plugins with `mi.load_dict`.

* `direct`   -- direct lighting (`direct` integrator), one point light, hard shadows from a
  sphere and a cube, a checkerboard floor receding to the horizon (period 1 unit, so far
  away it is well past Nyquist). A point light has no area to sample and the floor is
  diffuse: every sample is noise-free; the only randomness is the film position.
* `cornell`  -- Mitsuba's own Cornell box (`mi.cornell_box()`), path traced (`path`,
  max depth 8), the ceiling emitter (radiance ~18 in red) in view: Monte Carlo noise and a
  high dynamic range.
* `thinlens` -- `direct` seen through a thin lens (aperture radius 0.06, focus at 3 units):
  the image-plane integrand is smooth only after integration over the aperture.

`scene_dict(name, width, height, rfilter, spp)` returns the dict; the film's
reconstruction filter (`box`, `tent`, `gaussian`, `mitchell`, `lanczos`) and the sampler
(`multijitter`, Mitsuba's stratified sampler) are the only things that change between
Mitsuba's film renders.
"""

import mitsuba as mi

SCENES = ("direct", "cornell", "thinlens")
FILTERS = ("box", "tent", "gaussian", "mitchell", "lanczos")


def _film(width, height, rfilter):
    return {
        "type": "hdrfilm",
        "width": width,
        "height": height,
        "rfilter": {"type": rfilter},
        "pixel_format": "rgb",
        "component_format": "float32",
    }


def _sampler(spp):
    return {"type": "multijitter", "sample_count": spp}


def _outdoor(width, height, rfilter, spp, lens):
    T = mi.ScalarTransform4f
    to_world = T().look_at(origin=[0.0, 1.0, 4.0], target=[0.0, 0.55, -6.0], up=[0, 1, 0])
    if lens:
        sensor = {
            "type": "thinlens",
            "fov": 45.0,
            "aperture_radius": 0.06,
            "focus_distance": 3.0,
            "to_world": to_world,
        }
    else:
        sensor = {"type": "perspective", "fov": 45.0, "to_world": to_world}
    sensor["film"] = _film(width, height, rfilter)
    sensor["sampler"] = _sampler(spp)
    checker = {
        "type": "checkerboard",
        "color0": {"type": "rgb", "value": [0.08, 0.08, 0.1]},
        "color1": {"type": "rgb", "value": [0.85, 0.8, 0.7]},
        # The floor's uv square is 200 x 200 units; 200 periods: one period per unit.
        "to_uv": T().scale([200.0, 200.0, 1.0]),
    }
    return {
        "type": "scene",
        "integrator": {"type": "direct"},
        "sensor": sensor,
        "light": {
            "type": "point",
            "position": [2.0, 4.0, 2.0],
            "intensity": {"type": "rgb", "value": [70.0, 70.0, 70.0]},
        },
        "floor": {
            "type": "rectangle",
            "to_world": T().rotate([1, 0, 0], -90).scale([100.0, 100.0, 1.0]),
            "bsdf": {"type": "diffuse", "reflectance": checker},
        },
        "sphere": {
            "type": "sphere",
            "center": [-0.7, 0.5, 0.0],
            "radius": 0.5,
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.7, 0.2, 0.15]}},
        },
        "cube": {
            "type": "cube",
            "to_world": T().translate([0.9, 0.4, -1.5]).rotate([0, 1, 0], 30).scale(0.4),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.2, 0.4, 0.7]}},
        },
    }


def _cornell(width, height, rfilter, spp):
    d = mi.cornell_box()
    d["sensor"]["film"] = _film(width, height, rfilter)
    d["sensor"]["sampler"] = _sampler(spp)
    d["integrator"] = {"type": "path", "max_depth": 8}
    return d


def scene_dict(name, width, height, rfilter="box", spp=8):
    """The Mitsuba scene dict of `name` with the given film filter and sample count."""
    if name == "direct":
        return _outdoor(width, height, rfilter, spp, lens=False)
    if name == "thinlens":
        return _outdoor(width, height, rfilter, spp, lens=True)
    if name == "cornell":
        return _cornell(width, height, rfilter, spp)
    raise ValueError(f"unknown scene {name!r}; expected one of {SCENES}")


def load(name, width, height, rfilter="box", spp=8):
    """The loaded Mitsuba scene."""
    return mi.load_dict(scene_dict(name, width, height, rfilter, spp))
