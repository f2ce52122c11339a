"""Render time of a sphere with `polbrdf` and with `measured_polarized`
(docs/performance.md, "Mitsuba 3 plugin").

    python python/benches/render_sphere.py [--size 256] [--spp 16]

Builds the five-wavelength TiO2 paint of python/tests (with the binary
POLBRDF_BIN, default target/release/polbrdf), exports it for
measured_polarized, and renders the sphere of tests/test_mitsuba.py
(stokes + direct, a directional light) with each BSDF in
llvm_ad_spectral_polarized, three times each after a warm-up; then the same
with the path integrator (max_depth 4, BSDF and emitter sampling). Prints
the median wall time of each and the plugin's own set-up time.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))

import conftest  # noqa: E402  (the specs and the binary of the tests)
import mitsuba as mi  # noqa: E402

import polbrdf.mitsuba as pm  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--variant", default="llvm_ad_spectral_polarized")
    a = ap.parse_args()
    mi.set_variant(a.variant)
    pm.register()
    import test_mitsuba as tm

    work = tempfile.mkdtemp(prefix="polbrdf-bench-")
    spec = os.path.join(work, "paint5.json")
    with open(spec, "w") as f:
        json.dump(tm.PAINT5, f)
    table = os.path.join(work, "paint5.pbrdf")
    export = os.path.join(work, "paint5.pbsdf")
    subprocess.run([conftest.binary(), "solve", spec, "--table", table], check=True, capture_output=True)
    subprocess.run([conftest.binary(), "export", table, "--format", "mitsuba", "-o", export], check=True, capture_output=True)

    import numpy as np

    import polbrdf

    t = polbrdf.Table.load(table)
    rng = np.random.default_rng(0)

    def hemi(n):
        mu = rng.uniform(0, 1, n)
        ph = rng.uniform(0, 2 * np.pi, n)
        s = np.sqrt(1 - mu * mu)
        return np.stack([s * np.cos(ph), s * np.sin(ph), mu], axis=1)

    n = 1_000_000
    wi, wo = hemi(n), hemi(n)
    t0 = time.perf_counter()
    t.eval(wi, wo, 550.0)
    dt = time.perf_counter() - t0
    print(f"Table.eval: {n} random pairs at 550 nm (a table wavelength): {dt:.2f} s ({dt / n * 1e6:.2f} us per pair)")
    n = 250_000
    wi, wo = hemi(n), hemi(n)
    wl = rng.uniform(360, 830, (n, 4))
    t0 = time.perf_counter()
    t._native.eval_mitsuba(wi, wo, wl, np.ascontiguousarray(wi[:, 2]), np.ones(n, dtype=bool))
    dt = time.perf_counter() - t0
    print(f"eval_mitsuba: {n} lanes x 4 random wavelengths in 360-830 nm (clamped): {dt:.2f} s ({dt / n * 1e6:.2f} us per lane)")

    t0 = time.perf_counter()
    mi.load_dict({"type": "polbrdf", "filename": table})
    setup = time.perf_counter() - t0
    print(f"polbrdf plugin set-up (table read + sampling density): {setup * 1e3:.0f} ms")
    for integ in ("direct", "path"):
        for name, bsdf in (("polbrdf", {"type": "polbrdf", "filename": table}), ("measured_polarized", {"type": "measured_polarized", "filename": export})):
            sc = tm.sphere_scene(bsdf)
            sc["sensor"]["film"]["width"] = sc["sensor"]["film"]["height"] = a.size
            sc["sensor"]["sampler"]["sample_count"] = a.spp
            if integ == "path":
                sc["integrator"] = {"type": "stokes", "integrator": {"type": "path", "max_depth": 4}}
                sc["sky"] = {"type": "constant", "radiance": {"type": "d65", "scale": 0.2}}
            scene = mi.load_dict(sc)
            mi.render(scene, seed=0)  # warm-up (JIT compilation)
            times = []
            for s in range(3):
                t0 = time.perf_counter()
                img = mi.render(scene, seed=s + 1)
                _ = float(img.array[0]) if hasattr(img, "array") else None
                times.append(time.perf_counter() - t0)
            print(f"{integ:6s} {name:18s} {a.size}x{a.size} {a.spp} spp: {statistics.median(times):.2f} s (median of 3)")


if __name__ == "__main__":
    main()
