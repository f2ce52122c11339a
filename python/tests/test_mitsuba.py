"""`polbrdf.mitsuba` in the real Mitsuba 3 from PyPI (docs/python.md).

1. The plugin's `eval` is `polbrdf eval` put into Mitsuba's conventions by
   an independent implementation of the frame change here (Stokes rotation
   about each ray from our meridian x-axis to Mitsuba's `stokes_basis`, the
   V sign flip of conventions section 9, the cosine of the light), in both
   `scalar_spectral_polarized` and `llvm_ad_spectral_polarized`.
2. The specular delta of a bare mirror equals Mitsuba's own `conductor`
   (same n + ik): the check that can see the sign of V over a mirror.
3. Sampling passes Mitsuba's chi-square test against the plugin's `pdf`,
   and each sample's weight is `eval / pdf` of the direction drawn.
4. A sphere rendered with the plugin and with `measured_polarized`
   (`polbrdf export --format mitsuba`, five wavelengths) agree within the
   latter's resampling error (docs/mitsuba.md).
"""

import copy
import json
import glob
import math
import os

import numpy as np
import pytest

import polbrdf
from conftest import PAINT, TOKEN, cli, cli_eval

try:
    import drjit as dr
    import mitsuba as mi
except ImportError as e:  # pragma: no cover - exercised only without Mitsuba
    if os.environ.get("CI"):
        raise
    pytest.skip(f"SKIPPED LOUDLY: mitsuba is not installed ({e}); pip install mitsuba", allow_module_level=True)

import polbrdf.mitsuba as pm

SCALAR = "scalar_spectral_polarized"
LLVM = "llvm_ad_spectral_polarized"


def _llvm_available() -> bool:
    if "DRJIT_LIBLLVM_PATH" not in os.environ:
        found = sorted(glob.glob("/usr/lib/*/libLLVM-19.so*") + glob.glob("/usr/lib/*/libLLVM.so.19*"))
        if found:
            os.environ["DRJIT_LIBLLVM_PATH"] = found[0]
    try:
        mi.set_variant(LLVM)
        dr.eval(mi.Float([1.0, 2.0]) * 2)
        return True
    except Exception:  # noqa: BLE001 - Dr.Jit raises various types without LLVM
        return False


def use_llvm(what: str) -> None:
    """Switch to the LLVM variant with the plugin registered; without
    libLLVM 19 skip loudly (fail under CI)."""
    if not _llvm_available():
        if os.environ.get("CI"):
            pytest.fail(f"the {what} needs llvm_ad_spectral_polarized (libllvm19)")
        pytest.skip(f"SKIPPED LOUDLY: no libLLVM 19, so the {what} did not run")
    mi.set_variant(LLVM)
    pm.register()


VARIANTS = [SCALAR, LLVM]


@pytest.fixture(params=VARIANTS)
def variant(request):
    if request.param == LLVM and not _llvm_available():
        if os.environ.get("CI"):
            pytest.fail("the LLVM variant needs libLLVM 19 (apt-get install libllvm19)")
        pytest.skip("SKIPPED LOUDLY: no libLLVM 19 for llvm_ad_spectral_polarized (apt-get install libllvm19)")
    mi.set_variant(request.param)
    pm.register()
    return request.param


def to_np_mueller(m, n):
    """mi.Spectrum (Mueller of 4 wavelengths) as (n, 4 wl, 4, 4)."""
    a = np.array(m, dtype=float)
    if a.ndim == 3:  # scalar: (4 rows, 4 cols, 4 wl)
        a = a[..., None]
    assert a.shape == (4, 4, 4, n), a.shape  # (rows, cols, wl, lanes)
    return np.transpose(a, (3, 2, 0, 1))


def stokes_rotator(alpha):
    """Stokes vectors re-expressed in a basis whose x-axis is the old one
    turned by `alpha` about the ray (towards y = k x x): Q' = Q cos 2a + U
    sin 2a, U' = -Q sin 2a + U cos 2a (conventions section 5)."""
    c, s = np.cos(2 * alpha), np.sin(2 * alpha)
    r = np.zeros(alpha.shape + (4, 4))
    r[..., 0, 0] = r[..., 3, 3] = 1
    r[..., 1, 1] = r[..., 2, 2] = c
    r[..., 1, 2] = s
    r[..., 2, 1] = -s
    return r


def signed_angle(k, a, b):
    """Angle from `a` to `b` about `k` (right-handed)."""
    return np.arctan2(np.einsum("ij,ij->i", k, np.cross(a, b)), np.einsum("ij,ij->i", a, b))


def mitsuba_basis(k):
    return np.array([np.array(mi.mueller.stokes_basis(mi.Vector3f(*map(float, v)))).reshape(3) for v in k])


def meridian_x_of(w):
    """x = e_theta = (cos t cos p, cos t sin p, -sin t) of the graphics angles
    of `w` (conventions section 5: the incident ray's frame for the light,
    the outgoing ray's for the viewer)."""
    t, p = np.radians(angles(w))
    return np.stack([np.cos(t) * np.cos(p), np.cos(t) * np.sin(p), -np.sin(t)], axis=1)


def expected_mitsuba(f, light, view):
    """`polbrdf eval`'s f (n, 4, 4) at (light = our w_i, view = our w_o) as
    Mitsuba's BSDF value: D f D cos(theta_light), rotated from the meridian
    x-axes (conventions section 5) into Mitsuba's stokes_basis."""
    d = np.diag([1.0, 1.0, 1.0, -1.0])
    m = d @ f @ d * (light[:, 2] / np.linalg.norm(light, axis=1))[:, None, None]
    k_in, k_out = -light, view
    x_in = meridian_x_of(light)
    x_out = meridian_x_of(view)
    r_in = stokes_rotator(signed_angle(k_in, x_in, mitsuba_basis(k_in)))
    r_out = stokes_rotator(signed_angle(k_out, x_out, mitsuba_basis(k_out)))
    return r_out @ m @ np.transpose(r_in, (0, 2, 1))


def unit(v):
    """Unit vectors, rounded to float32 as Mitsuba holds them."""
    v = np.asarray(v, dtype=float)
    return (v / np.linalg.norm(v, axis=1, keepdims=True)).astype(np.float32).astype(float)


def random_hemisphere(rng, n, max_theta_deg=85.0):
    mu = rng.uniform(math.cos(math.radians(max_theta_deg)), 1.0, n)
    phi = rng.uniform(0, 2 * math.pi, n)
    s = np.sqrt(1 - mu**2)
    return np.stack([s * np.cos(phi), s * np.sin(phi), mu], axis=1).astype(np.float32).astype(float)


def make_si(view, wavelengths, scalar):
    n = view.shape[0]
    if scalar:
        si = dr.zeros(mi.SurfaceInteraction3f)
        si.wi = mi.Vector3f(view[0])
        si.wavelengths = mi.UnpolarizedSpectrum(wavelengths[0])
    else:
        si = dr.zeros(mi.SurfaceInteraction3f, n)
        si.wi = mi.Vector3f(np.ascontiguousarray(view.T))
        si.wavelengths = mi.UnpolarizedSpectrum(np.ascontiguousarray(wavelengths.T.astype(np.float32)))
    return si


def plugin_eval(bsdf, light, view, wavelengths, scalar, importance=False):
    """The plugin's eval at each lane: (n, 4 wl, 4, 4). In radiance mode
    `si.wi` is the viewer and `wo` the light; in importance mode the other
    way round."""
    ctx = mi.BSDFContext(mi.TransportMode.Importance) if importance else mi.BSDFContext()
    a, b = (light, view) if importance else (view, light)
    if scalar:
        out = []
        for k in range(a.shape[0]):
            si = make_si(a[k : k + 1], wavelengths[k : k + 1], True)
            out.append(to_np_mueller(bsdf.eval(ctx, si, mi.Vector3f(b[k])), 1)[0])
        return np.array(out)
    si = make_si(a, wavelengths, False)
    return to_np_mueller(bsdf.eval(ctx, si, mi.Vector3f(np.ascontiguousarray(b.T))), a.shape[0])


def angles(w):
    t = np.degrees(np.arctan2(np.hypot(w[:, 0], w[:, 1]), w[:, 2]))
    p = np.degrees(np.arctan2(w[:, 1], w[:, 0]))
    return t, p


def test_eval_is_polbrdf_eval_in_mitsuba_frames(variant, paint_files):
    _, table_path = paint_files
    bsdf = mi.load_dict({"type": "polbrdf", "filename": str(table_path)})
    rng = np.random.default_rng(5)
    n = 12
    light = random_hemisphere(rng, n)
    view = random_hemisphere(rng, n)
    wl = rng.uniform(450, 650, (n, 4)).astype(np.float32).astype(float)
    got = plugin_eval(bsdf, light, view, wl, variant == SCALAR)
    ti, pi = angles(light)
    to, po = angles(view)
    pairs = np.stack([ti, pi, to, po], axis=1)
    worst = 0.0
    scale = 0.0
    for c in range(4):
        want_f = np.array([cli_eval(table_path, pairs[k : k + 1], wl[k, c])[0][0] for k in range(n)])
        want = expected_mitsuba(want_f, light, view)
        scale = max(scale, np.abs(want_f[:, 0, 0]).max())
        worst = max(worst, np.abs(got[:, c] - want).max())
        # The check can fail: without the V flip the answer is far off.
        d = np.diag([1.0, 1.0, 1.0, -1.0])
        assert np.abs(got[:, c] - d @ want @ d).max() > 1e-3 * scale
    print(f"eval: worst {worst:.3g} of max f11 {scale:.4g} ({worst / scale:.2g})")
    assert worst <= 1e-6 * scale, (worst, scale)
    # Importance mode: the same light path, with the cosine of Mitsuba's wo
    # (now the viewer side) instead of the light's.
    imp = plugin_eval(bsdf, light, view, wl, variant == SCALAR, importance=True)
    ratio = (view[:, 2] / light[:, 2])[:, None, None, None]
    assert np.abs(imp - got * ratio).max() <= 1e-5 * np.abs(got * ratio).max()


SILVER_MIRROR = {
    "layers": [{"optical_thickness": 0.0, "scatterer": {"henyey_greenstein": {"albedo": 0.5, "g": 0.3}}}],
    "base": {"fresnel": {"material": {"n": 1.2, "k": 7.0}}},
    "wavelengths_nm": [500, 600],
    "solver": {"streams": 8},
}


@pytest.fixture(scope="module")
def mirror_table(tmp_path_factory):
    path = tmp_path_factory.mktemp("mirror") / "mirror.pbrdf"
    polbrdf.solve(SILVER_MIRROR).save(path)
    return path


def test_the_delta_lobe_is_mitsubas_conductor(variant, mirror_table):
    ours = mi.load_dict({"type": "polbrdf", "filename": str(mirror_table)})
    theirs = mi.load_dict({"type": "conductor", "eta": 1.2, "k": 7.0})
    rng = np.random.default_rng(9)
    n = 16
    view = random_hemisphere(rng, n, 88.0)
    wl = np.full((n, 4), 550.0)
    ctx = mi.BSDFContext()
    scalar = variant == SCALAR
    got, want, wos = [], [], []
    for k in range(n) if scalar else [slice(None)]:
        v = view[k : k + 1] if scalar else view
        si = make_si(v, wl[k : k + 1] if scalar else wl, scalar)
        m = v.shape[0]
        s1 = mi.Float(0.0) if scalar else dr.zeros(mi.Float, m)
        s2 = mi.Point2f(0.5, 0.5) if scalar else dr.full(mi.Point2f, 0.5, m)
        bs, w = ours.sample(ctx, si, s1, s2)
        bs2, w2 = theirs.sample(ctx, si, s1, s2)
        assert np.all(np.array(bs.sampled_type) == int(mi.BSDFFlags.DeltaReflection))
        got.append(to_np_mueller(w, m) * np.array(bs.pdf).reshape(-1)[:, None, None, None])
        want.append(to_np_mueller(w2, m))
        wos.append(np.array(bs.wo).reshape(3, -1).T)
    got, want = np.concatenate(got), np.concatenate(want)
    wo = np.concatenate(wos)
    assert np.allclose(wo, view * np.array([-1, -1, 1]), atol=1e-6)
    # The V row and column are visible: they would flip without the sign change.
    assert np.abs(want[..., 2:, 2:]).max() > 0.3
    print(f"delta vs conductor: {np.abs(got - want).max():.3g}")
    assert np.abs(got - want).max() <= 2e-6, np.abs(got - want).max()


def sample_functors(bsdf, wi, skip_delta=True):
    ctx = mi.BSDFContext()

    def si_of(n):
        si = dr.zeros(mi.SurfaceInteraction3f, n)
        si.wi = mi.Vector3f(*wi)
        si.wavelengths = mi.UnpolarizedSpectrum(550.0)
        return si

    def sample(s, *args):
        n = dr.width(s)
        bs, weight = bsdf.sample(ctx, si_of(n), s[0], mi.Point2f(s[1], s[2]))
        w = np.where(np.array(weight[0][0]).reshape(4, -1)[0] != 0, 1.0, 0.0)
        if skip_delta:
            w = np.where(np.array(bs.sampled_type) == int(mi.BSDFFlags.DeltaReflection), 0.0, w)
        return bs.wo, mi.Float(w)

    def pdf(wo, *args):
        return bsdf.pdf(ctx, si_of(dr.width(wo)), wo)

    return sample, pdf


@pytest.mark.parametrize(
    "which, theta_deg", [("paint", 0.0), ("paint", 45.0), ("paint", 80.0), ("silver", 45.0)]
)
def test_sampling_passes_the_chi_square_test(paint_files, silver_files, which, theta_deg, tmp_path, monkeypatch):
    """The diffuse lobe's samples against its pdf (over silver the delta
    lobe's samples are left out of the histogram, as its pdf excludes them;
    the rejection writes chi2_data.py into the working directory)."""
    monkeypatch.chdir(tmp_path)
    use_llvm("chi-square test")
    from mitsuba.chi2 import ChiSquareTest, SphericalDomain

    table = (paint_files if which == "paint" else silver_files)[1]
    bsdf = mi.load_dict({"type": "polbrdf", "filename": str(table)})
    t = math.radians(theta_deg)
    sample, pdf = sample_functors(bsdf, [math.sin(t), 0.0, math.cos(t)])
    chi2 = ChiSquareTest(domain=SphericalDomain(), sample_func=sample, pdf_func=pdf, sample_dim=3, sample_count=400000)
    assert chi2.run(), chi2.messages


@pytest.mark.parametrize("mode", ["radiance", "importance"])
def test_sample_weight_is_eval_over_pdf(variant, paint_files, silver_files, mode):
    scalar = variant == SCALAR
    ctx = mi.BSDFContext(mi.TransportMode.Importance if mode == "importance" else mi.TransportMode.Radiance)
    for path in (paint_files[1], silver_files[1]):
        bsdf = mi.load_dict({"type": "polbrdf", "filename": str(path)})
        rng = np.random.default_rng(2)
        n = 8 if scalar else 256
        view = random_hemisphere(rng, n, 80.0)
        wl = rng.uniform(450, 650, (n, 4))
        u = rng.uniform(0, 1, (n, 3)).astype(np.float32)
        for k in range(n) if scalar else [slice(None)]:
            v = view[k : k + 1] if scalar else view
            m = v.shape[0]
            si = make_si(v, wl[k : k + 1] if scalar else wl, scalar)
            uu = u[k : k + 1] if scalar else u
            s1 = mi.Float(float(uu[0, 0])) if scalar else mi.Float(uu[:, 0])
            s2 = mi.Point2f(float(uu[0, 1]), float(uu[0, 2])) if scalar else mi.Point2f(uu[:, 1], uu[:, 2])
            bs, w = bsdf.sample(ctx, si, s1, s2)
            glossy = np.array(bs.sampled_type).reshape(-1) == int(mi.BSDFFlags.GlossyReflection)
            pdf = np.array(bs.pdf).reshape(-1)
            ok = glossy & (pdf > 0)
            if not ok.any():
                continue
            ev = to_np_mueller(bsdf.eval(ctx, si, bs.wo), m)
            pd = np.array(bsdf.pdf(ctx, si, bs.wo)).reshape(-1)
            ww = to_np_mueller(w, m)
            assert np.allclose(pd[ok], pdf[ok], rtol=1e-5)
            ratio = ev[ok] / pd[ok][:, None, None, None]
            assert np.abs(ww[ok] - ratio).max() <= 1e-5 * np.abs(ratio[..., 0, 0]).max()


PAINT5 = copy.deepcopy(PAINT)
PAINT5["wavelengths_nm"] = [450, 500, 550, 600, 650]


def sphere_scene(bsdf):
    return {
        "type": "scene",
        "integrator": {"type": "stokes", "integrator": {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0}},
        "sensor": {
            "type": "perspective",
            "fov": 30,
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": 48, "height": 48, "rfilter": {"type": "box"}},
            "sampler": {"type": "independent", "sample_count": 4},
        },
        "light": {"type": "directional", "direction": [-0.4, -0.3, -1.0], "irradiance": {"type": "d65", "scale": 1.0}},
        "sphere": {"type": "sphere", "bsdf": bsdf},
    }


def test_sphere_render_agrees_with_measured_polarized(tmp_path, workdir):
    use_llvm("render comparison")
    spec = workdir / "paint5.json"
    spec.write_text(json.dumps(PAINT5))
    table = workdir / "paint5.pbrdf"
    cli("solve", spec, "--table", table)
    export = tmp_path / "paint5.pbsdf"
    cli("export", table, "--format", "mitsuba", "-o", export)
    ours = mi.render(mi.load_dict(sphere_scene({"type": "polbrdf", "filename": str(table)})), seed=1)
    theirs = mi.render(mi.load_dict(sphere_scene({"type": "measured_polarized", "filename": str(export)})), seed=1)
    a, b = np.array(ours), np.array(theirs)
    # Channels: RGB, then S0..S3 (each RGB) of the stokes integrator.
    s0_b = b[..., :3]
    scale = s0_b.max()
    assert scale > 0
    lit = s0_b[..., 1] > 1e-3 * scale
    assert lit.sum() > 200
    diff = np.abs(a - b)
    mean_rel = diff[lit].mean() / scale
    max_rel = diff[lit].max() / scale
    # measured_polarized's resampling error (docs/mitsuba.md): 1.2e-3 of
    # max f11 below 60 deg, 3.4e-3 below 80 deg, 8e-2 over the hemisphere.
    print(f"render: mean {mean_rel:.3g}, max {max_rel:.3g} of max S0 over {lit.sum()} lit pixels")
    assert mean_rel <= 5e-3, mean_rel
    assert max_rel <= 0.1, max_rel
    # Polarization is there to compare (S1 of the sphere's rim).
    assert np.abs(a[..., 6:9]).max() > 1e-3 * scale


def test_mirror_sphere_path_traced_is_mitsubas_conductor(tmp_path):
    """A bare mirror (optical thickness 0 over n = 1.2 + 7i) path-traced
    under a constant sky with the stokes integrator: every camera ray takes
    the delta lobe once, so the image (intensity and S1, S2 of the
    reflection) equals Mitsuba's conductor sphere to float precision."""
    use_llvm("path-traced comparison")
    path = tmp_path / "mirror.pbrdf"
    polbrdf.solve(SILVER_MIRROR).save(path)

    def scene(bsdf):
        sc = sphere_scene(bsdf)
        sc["integrator"] = {"type": "stokes", "integrator": {"type": "path", "max_depth": 3}}
        del sc["light"]
        sc["sky"] = {"type": "constant", "radiance": {"type": "d65", "scale": 1.0}}
        return sc

    ours = np.array(mi.render(mi.load_dict(scene({"type": "polbrdf", "filename": str(path)})), seed=3))
    theirs = np.array(mi.render(mi.load_dict(scene({"type": "conductor", "eta": 1.2, "k": 7.0})), seed=3))
    scale = np.abs(theirs[..., :3]).max()
    assert np.abs(theirs[..., 6:12]).max() > 1e-2 * scale  # S1, S2 present
    diff = np.abs(ours - theirs).max() / scale
    print(f"mirror sphere vs conductor: {diff:.3g} of max S0")
    assert diff <= 1e-5, diff


def test_plugin_loads_a_service_url_and_refuses_what_it_cannot_render(service, tmp_path):
    """`{"type": "polbrdf", "url": ...}` fetches through the render-node
    cache (`cache_dir`) and evaluates as the file does; a table of part of
    the incident directions or of part of the Mueller matrix is refused by
    name, and so is a spec with neither or both of filename and url."""
    mi.set_variant(SCALAR)
    pm.register()
    client = polbrdf.Client(service, token=TOKEN)
    spec = copy.deepcopy(PAINT)
    spec["wavelengths_nm"] = [500, 600]
    job = client.submit(spec)
    client.wait(job, timeout_s=120)
    url = f"{service}/v1/brdfs/{job['id']}"
    local = tmp_path / "local.pbrdf"
    polbrdf.solve(spec).save(local)
    by_url = mi.load_dict({"type": "polbrdf", "url": url, "cache_dir": str(tmp_path / "cache")})
    by_file = mi.load_dict({"type": "polbrdf", "filename": str(local)})
    light = np.array([[0.3, 0.1, 0.9]])
    view = np.array([[-0.5, 0.2, 0.8]])
    wl = np.array([[510.0, 550.0, 590.0, 700.0]])
    a = plugin_eval(by_url, light, view, wl, True)
    b = plugin_eval(by_file, light, view, wl, True)
    assert np.array_equal(a, b) and np.abs(a).max() > 0
    assert any((tmp_path / "cache").iterdir())
    partial = copy.deepcopy(spec)
    partial["needs"]["theta_i_deg"] = [30.0]
    polbrdf.solve(partial).save(tmp_path / "partial.pbrdf")
    with pytest.raises(Exception, match="incident directions"):
        mi.load_dict({"type": "polbrdf", "filename": str(tmp_path / "partial.pbrdf")})
    scalar_only = copy.deepcopy(spec)
    scalar_only["needs"]["stokes"] = "intensity"
    polbrdf.solve(scalar_only).save(tmp_path / "intensity.pbrdf")
    with pytest.raises(Exception, match="4x4 table"):
        mi.load_dict({"type": "polbrdf", "filename": str(tmp_path / "intensity.pbrdf")})
    with pytest.raises(Exception, match="exactly one"):
        mi.load_dict({"type": "polbrdf"})


def test_a_wavelength_free_table_renders_at_every_wavelength(variant, tmp_path):
    spec = {
        "layers": [{"optical_thickness": 2.0, "scatterer": {"rayleigh": {"albedo": 0.9}}}],
        "base": {"lambertian": {"albedo": 0.5}},
        "solver": {"streams": 8},
        "needs": {"grid": {"polar_nodes": 16}},
    }
    path = tmp_path / "grey.pbrdf"
    table = polbrdf.solve(spec)
    assert len(table.wavelengths_nm) == 0
    table.save(path)
    bsdf = mi.load_dict({"type": "polbrdf", "filename": str(path)})
    light = unit([[0.3, 0.1, 0.9], [0.0, 0.6, 0.8]])
    view = unit([[-0.5, 0.2, 0.8], [0.6, 0.0, 0.8]])
    wl = np.array([[400.0, 500.0, 600.0, 700.0], [380.0, 450.0, 720.0, 800.0]])
    got = plugin_eval(bsdf, light, view, wl, variant == SCALAR)
    f = table.eval(light, view)
    want = expected_mitsuba(f, light, view)
    for c in range(4):
        assert np.abs(got[:, c] - want).max() <= 1e-6 * np.abs(f[:, 0, 0]).max()


def test_inactive_and_nan_lanes_give_zeros_not_nans(paint_files):
    """Lanes Mitsuba marks inactive (their directions may be NaN) and
    directions below the surface evaluate, sample and weigh to 0, without
    an exception and without a NaN in the other lanes."""
    use_llvm("NaN-lane check")
    bsdf = mi.load_dict({"type": "polbrdf", "filename": str(paint_files[1])})
    view = np.array([[0.0, 0.6, 0.8], [np.nan, np.nan, np.nan], [0.0, 0.6, -0.8], [0.6, 0.0, 0.8]])
    light = np.array([[0.3, 0.0, 0.9539392], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [np.nan, 0.0, np.nan]])
    wl = np.full((4, 4), 550.0)
    ctx = mi.BSDFContext()
    si = make_si(view, wl, False)
    active = mi.Bool(np.array([True, False, True, True]))
    m = to_np_mueller(bsdf.eval(ctx, si, mi.Vector3f(np.ascontiguousarray(light.T)), active), 4)
    assert np.isfinite(m).all()
    assert np.abs(m[0]).max() > 0 and np.all(m[1:] == 0)
    p = np.array(bsdf.pdf(ctx, si, mi.Vector3f(np.ascontiguousarray(light.T)), active))
    assert np.isfinite(p).all() and p[0] > 0 and np.all(p[1:] == 0)
    bs, w = bsdf.sample(ctx, si, mi.Float([0.3] * 4), mi.Point2f([0.4] * 4, [0.6] * 4), active)
    w = to_np_mueller(w, 4)
    assert np.isfinite(w).all() and np.abs(w[0]).max() > 0 and np.all(w[1:3] == 0)
