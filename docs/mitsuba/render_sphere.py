#!/usr/bin/env python3
"""Render a sphere painted with a polbrdf Mitsuba export (docs/mitsuba.md).

Mitsuba 3 (`scalar_spectral_polarized`, `stokes` integrator around `path`):
a unit sphere with the `measured_polarized` BSDF of TENSOR_FILE, lit by a
directional light (D65) from the upper left front (phase angle 54.7 degrees),
seen by a perspective camera on the +z axis. Writes

  OUT_DIR/mitsuba-sphere-intensity.png  S0 in sRGB, scaled so the brightest
                                        pixel's luminance is 0.9
  OUT_DIR/mitsuba-sphere-dop.png        degree of polarization
                                        sqrt(S1^2 + S2^2 + S3^2) / S0 of the
                                        luminance of each Stokes component,
                                        colour map black (0) - purple - orange -
                                        light yellow (DOP_MAX and above)

Usage: render_sphere.py TENSOR_FILE [--out-dir docs/images] [--size 256]
                        [--spp 128] [--dop-max 0.3]
"""

import argparse
import os
import time

import drjit as dr
import mitsuba as mi


def luminance(img, c):
    """Luminance of Stokes component c (channels S<c>.R, .G, .B)."""
    b = 3 + 3 * c
    return 0.2126 * img[:, :, b] + 0.7152 * img[:, :, b + 1] + 0.0722 * img[:, :, b + 2]


def colormap(t):
    """Piecewise linear map of t in [0, 1] to RGB (black, purple, orange, light yellow)."""
    anchors = [
        (0.0, (0.0, 0.0, 0.0)),
        (0.35, (0.45, 0.10, 0.55)),
        (0.7, (0.95, 0.45, 0.10)),
        (1.0, (1.0, 1.0, 0.75)),
    ]
    t = dr.clip(t, 0.0, 1.0)
    out = []
    for ch in range(3):
        v = dr.zeros(mi.TensorXf, t.shape)
        for (t0, c0), (t1, c1) in zip(anchors, anchors[1:]):
            w = dr.clip((t - t0) / (t1 - t0), 0.0, 1.0)
            inside = (t >= t0) & (t <= t1)
            v = dr.select(inside, c0[ch] + (c1[ch] - c0[ch]) * w, v)
        out.append(v)
    return out


def stack(channels):
    """(H, W) tensors to one (H, W, len) tensor."""
    h, w = channels[0].shape
    flat = [list(c.array) for c in channels]
    data = [v for px in zip(*flat) for v in px]
    return mi.TensorXf(dr.scalar.ArrayXf(data), (h, w, len(channels)))


def write_png(tensor, path, display_referred=False):
    """8-bit sRGB PNG; linear data get the sRGB curve, display-referred don't."""
    bmp = mi.Bitmap(tensor, mi.Bitmap.PixelFormat.RGB)
    bmp.set_srgb_gamma(display_referred)
    bmp.convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, srgb_gamma=True).write(path)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("tensor_file")
    ap.add_argument("--out-dir", default="docs/images")
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--dop-max", type=float, default=0.3)
    a = ap.parse_args()

    mi.set_variant("scalar_spectral_polarized")
    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "stokes", "integrator": {"type": "path", "max_depth": 3}},
        "sensor": {
            "type": "perspective",
            "fov": 30,
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": a.size, "height": a.size,
                     "rfilter": {"type": "gaussian"}},
            "sampler": {"type": "independent", "sample_count": a.spp, "seed": 1},
        },
        "sphere": {
            "type": "sphere",
            "bsdf": {"type": "measured_polarized", "filename": a.tensor_file,
                     "alpha_sample": 0.5},
        },
        "sun": {"type": "directional", "direction": [1, -1, -1],
                "irradiance": {"type": "d65", "scale": 3.0}},
    })
    t0 = time.time()
    img = mi.render(scene)
    seconds = time.time() - t0

    s0, s1, s2, s3 = (luminance(img, c) for c in range(4))
    scale = 0.9 / dr.max(s0.array)
    rgb = stack([img[:, :, 3 + k] * scale for k in range(3)])
    valid = s0 > 1e-4 * dr.max(s0.array)
    dop = dr.select(valid, dr.sqrt(s1 * s1 + s2 * s2 + s3 * s3) / dr.maximum(s0, 1e-12), 0.0)
    cm = stack(colormap(dop / a.dop_max))

    os.makedirs(a.out_dir, exist_ok=True)
    p_int = os.path.join(a.out_dir, "mitsuba-sphere-intensity.png")
    p_dop = os.path.join(a.out_dir, "mitsuba-sphere-dop.png")
    write_png(rgb, p_int)
    write_png(cm, p_dop, display_referred=True)
    lit = dr.sum(dr.select(valid, 1.0, 0.0).array)
    mean_dop = dr.sum(dr.select(valid, dop, 0.0).array) / lit
    print(f"rendered {a.size}x{a.size} at {a.spp} spp in {seconds:.1f} s (Mitsuba {mi.__version__}); "
          f"degree of polarization over the lit sphere: mean {mean_dop:.3f}, "
          f"max {dr.max(dop.array):.3f}; wrote {p_int}, {p_dop}")


if __name__ == "__main__":
    main()
