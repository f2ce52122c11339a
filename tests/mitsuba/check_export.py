#!/usr/bin/env python3
"""Evaluate a polbrdf Mitsuba export with the real Mitsuba 3 (tests/mitsuba_export.rs).

Loads TENSOR_FILE with the `measured_polarized` plugin in the
`scalar_spectral_polarized` variant and evaluates it through Mitsuba's Python
API at seeded random direction pairs (both uniform in solid angle over the
upper hemisphere) at the given wavelengths. Also samples Mitsuba's own smooth
`conductor` (a Fresnel mirror) at a few incident directions, which anchors the
sign convention of the circular Stokes component (docs/conventions.md §9).

Directions are written in polbrdf's graphics convention: `wi` points to the
light (Mitsuba's `wo` in radiance mode), `wo` to the viewer (Mitsuba's
`si.wi`), local frame z = normal. Each Mueller matrix is what Mitsuba returns,
cosine factor included, referred to Mitsuba's implicit Stokes bases, written
as `basis_in = stokes_basis(-wi)` (incident ray) and `basis_out =
stokes_basis(wo)` (outgoing ray); row = outgoing Stokes component.

Usage: check_export.py TENSOR_FILE OUT.json --pairs N --seed S
       --wavelengths 450,500,550,600,650 [--conductor-eta 1.2 --conductor-k 7]
"""

import argparse
import json
import math
import random
import time

import drjit as dr
import mitsuba as mi


def hemisphere(rng):
    z = 1.0 - rng.random()
    p = 2.0 * math.pi * rng.random()
    r = math.sqrt(max(0.0, 1.0 - z * z))
    return [r * math.cos(p), r * math.sin(p), z]


def vec(v):
    return [float(v[0]), float(v[1]), float(v[2])]


def interaction(view, wavelengths):
    si = dr.zeros(mi.SurfaceInteraction3f)
    si.p = mi.Point3f(0.0, 0.0, 0.0)
    si.n = mi.Normal3f(0.0, 0.0, 1.0)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
    si.wi = mi.Vector3f(*view)
    si.wavelengths = mi.UnpolarizedSpectrum(*wavelengths)
    return si


def mueller(value, k):
    """Wavelength sample k of a polarized Spectrum as a 4x4 list (row, column)."""
    return [[float(value[i][j][k]) for j in range(4)] for i in range(4)]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("tensor_file")
    ap.add_argument("out")
    ap.add_argument("--pairs", type=int, default=300)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--wavelengths", required=True)
    ap.add_argument("--conductor-eta", type=float, default=1.2)
    ap.add_argument("--conductor-k", type=float, default=7.0)
    ap.add_argument("--conductor-pairs", type=int, default=8)
    a = ap.parse_args()

    mi.set_variant("scalar_spectral_polarized")
    t0 = time.time()
    bsdf = mi.load_dict({"type": "measured_polarized", "filename": a.tensor_file})
    t_load = time.time() - t0
    ctx = mi.BSDFContext()  # radiance mode: light arrives along -wo, leaves along si.wi
    wl = [float(w) for w in a.wavelengths.split(",")]
    # The spectrum carries four wavelengths at a time.
    batches = [wl[i:i + 4] for i in range(0, len(wl), 4)]

    rng = random.Random(a.seed)
    pairs = []
    t0 = time.time()
    for _ in range(a.pairs):
        light, view = hemisphere(rng), hemisphere(rng)
        ms = []
        for b in batches:
            padded = b + [b[-1]] * (4 - len(b))
            si = interaction(view, padded)
            value = bsdf.eval(ctx, si, mi.Vector3f(*light))
            ms.extend(mueller(value, k) for k in range(len(b)))
        pairs.append({
            "wi": light,
            "wo": view,
            "basis_in": vec(mi.mueller.stokes_basis(-mi.Vector3f(*light))),
            "basis_out": vec(mi.mueller.stokes_basis(mi.Vector3f(*view))),
            "mueller": ms,
        })
    t_eval = time.time() - t0

    cond = mi.load_dict({"type": "conductor", "eta": a.conductor_eta, "k": a.conductor_k})
    mirror = []
    for _ in range(a.conductor_pairs):
        view = hemisphere(rng)
        si = interaction(view, [550.0] * 4)
        bs, value = cond.sample(ctx, si, 0.5, mi.Point2f(0.5, 0.5))
        light = vec(bs.wo)
        mirror.append({
            "wi": light,
            "wo": view,
            "basis_in": vec(mi.mueller.stokes_basis(-mi.Vector3f(*light))),
            "basis_out": vec(mi.mueller.stokes_basis(mi.Vector3f(*view))),
            "pdf": float(bs.pdf),
            "mueller": mueller(value, 0),
        })

    out = {
        "mitsuba_version": mi.__version__,
        "drjit_version": dr.__version__,
        "variant": mi.variant(),
        "wavelengths_nm": wl,
        "seconds_load": t_load,
        "seconds_eval": t_eval,
        "pairs": pairs,
        "conductor": {"eta": a.conductor_eta, "k": a.conductor_k, "pairs": mirror},
    }
    with open(a.out, "w") as f:
        json.dump(out, f)


if __name__ == "__main__":
    main()
