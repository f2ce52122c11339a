"""A Mitsuba 3 BSDF that evaluates polbrdf tables directly (docs/python.md).

>>> import mitsuba as mi
>>> mi.set_variant("llvm_ad_spectral_polarized")   # or scalar_spectral_polarized
>>> import polbrdf.mitsuba
>>> polbrdf.mitsuba.register()
>>> bsdf = mi.load_dict({"type": "polbrdf", "filename": "paint.pbrdf"})
>>> # or {"type": "polbrdf", "url": "http://farm:8080/v1/brdfs/ID"}

Unlike ``measured_polarized`` (which reads a resampled Rusinkiewicz grid of
exactly five wavelengths, docs/mitsuba.md) this plugin evaluates the table
itself: the exact Fourier sum in azimuth, polbrdf's own interpolation in the
polar cosines, linear interpolation between any number of wavelengths
(clamped to the table's range), and the specular reflection of a mirror base
(or a smooth top interface) as a Dirac delta lobe. Its ``eval`` is
``polbrdf eval`` converted to Mitsuba's conventions (docs/conventions.md
section 9):

* light and viewer: in radiance mode Mitsuba's ``wo`` is the light (our
  ``wi``) and ``si.wi`` the viewer (our ``wo``); swapped in importance mode;
* Stokes frames: the table's meridian frames (conventions section 5) are
  turned into Mitsuba's ``stokes_basis`` of the incident ray ``-wo`` and the
  outgoing ray ``si.wi`` by ``mi.mueller.rotate_mueller_basis``;
* circular polarization: Mitsuba's V is minus ours, so
  ``M = D f D``, ``D = diag(1, 1, 1, -1)`` (conventions section 9);
* the cosine of Mitsuba's ``wo`` (the light in radiance mode) multiplies
  the result, as Mitsuba's BSDFs return ``f cos``.

Sampling draws the light direction from a piecewise-constant density in
``(cos t, phi)`` proportional to ``f11 cos`` (tabulated at the table's polar
nodes, 32 x 32 cells over the hemisphere, with a 5 % floor so that every
direction the BSDF reflects into can be sampled), picks the delta lobe with
probability ``S00 / (S00 + diffuse albedo)``, and reports that pdf.

The work per call is done in NumPy and in polbrdf's Rust code (released
GIL, all cores) on whole wavefronts: in the JIT variants ``register()``
turns off Dr.Jit's symbolic loops and calls
(``dr.JitFlag.SymbolicLoops``, ``dr.JitFlag.SymbolicCalls``) so that the
integrator's lanes reach the plugin as evaluated arrays; the flags stay off
for the rest of the process (pass ``set_jit_flags=False`` to manage them
yourself).
"""

from __future__ import annotations

import math
import numpy as np

from . import Table

#: Cells of the sampling density in ``cos(theta)`` and in ``|dphi|`` (0 to pi).
SAMPLING_CELLS = (32, 32)
#: Floor of the sampling density, relative to its mean over the hemisphere.
SAMPLING_FLOOR = 0.05
#: At most this many of the table's wavelengths are averaged into the
#: sampling density.
SAMPLING_WAVELENGTHS = 5

_D_V = np.array([1.0, 1.0, 1.0, -1.0])


def _columns(v, n: int) -> np.ndarray:
    """A Dr.Jit direction (scalar or JIT 3-vector) as ``(n, 3)`` unit
    vectors (Mitsuba's Stokes bases are defined for unit vectors)."""
    a = np.asarray(v, dtype=float)
    a = a[None, :] if a.ndim == 1 else a.T
    norm = np.linalg.norm(a, axis=1, keepdims=True)
    a = a / np.where(norm > 0, norm, 1.0)
    return np.ascontiguousarray(np.broadcast_to(a, (n, 3)))


def _lanes(v, n: int) -> np.ndarray:
    """A Dr.Jit scalar-per-lane array (Float, Bool) as ``(n,)``."""
    a = np.asarray(v)
    return np.broadcast_to(a.reshape(-1), (n,)).copy() if a.size in (1, n) else a


def meridian_x(w: np.ndarray) -> np.ndarray:
    """The x-axes of the meridian Stokes frames of conventions section 5 for
    directions ``w`` ``(n, 3)`` pointing away from the surface: the same
    ``(cos t cos p, cos t sin p, -sin t)`` for the incident ray ``-w`` and
    the outgoing ray ``w``; at the normal ``p = 0`` (``brdf::angles``)."""
    rho = np.hypot(w[:, 0], w[:, 1])
    norm = np.linalg.norm(w, axis=1)
    ct = w[:, 2] / norm
    st = rho / norm
    safe = rho > 0
    cp = np.where(safe, w[:, 0] / np.where(safe, rho, 1.0), 1.0)
    sp = np.where(safe, w[:, 1] / np.where(safe, rho, 1.0), 0.0)
    return np.stack([ct * cp, ct * sp, -st], axis=1)


class SamplingDensity:
    """The piecewise-constant density of light directions given the known
    (viewer) direction: for the table's polar node nearest to the known
    direction, ``NU x NV`` cells in ``(mu, |dphi|)`` (``mu`` the sampled
    direction's cosine, ``dphi`` its azimuth relative to the mirror side),
    each holding the largest ``f11 mu`` at its corners and centre plus a
    floor; mirror-symmetric in ``dphi`` (f11 of an isotropic BRDF is)."""

    def __init__(self, table: Table, cells=SAMPLING_CELLS, floor=SAMPLING_FLOOR):
        nu, nv = cells
        self.nu, self.nv = nu, nv
        self.theta_nodes = table.theta_deg
        wls = table.wavelengths_nm
        if len(wls) > SAMPLING_WAVELENGTHS:
            wls = wls[np.linspace(0, len(wls) - 1, SAMPLING_WAVELENGTHS).round().astype(int)]
        mu_c = np.linspace(0.0, 1.0, nu + 1)
        ph_c = np.linspace(0.0, math.pi, nv + 1)
        mu_m = (mu_c[:-1] + mu_c[1:]) / 2
        ph_m = (ph_c[:-1] + ph_c[1:]) / 2
        k = len(self.theta_nodes)
        self.p_cell = np.empty((k, nu, nv))
        self.p_spec = np.zeros(k)
        area = (1.0 / nu) * (math.pi / nv) * 2.0  # both signs of dphi
        for n, theta in enumerate(self.theta_nodes):
            known = _unit(theta, 0.0)
            corners = self._g(table, known, mu_c[:, None], ph_c[None, :], wls)
            centres = self._g(table, known, mu_m[:, None], ph_m[None, :], wls)
            value = np.maximum.reduce(
                [corners[:-1, :-1], corners[1:, :-1], corners[:-1, 1:], corners[1:, 1:], centres]
            )
            albedo = float(np.sum(centres) * area)
            value = value + floor * max(float(np.mean(value)), 1e-300)
            self.p_cell[n] = value / value.sum()
            if table.has_specular:
                s00 = float(
                    np.mean([table.specular(known, w, clamp_wavelength=True)[0, 0] for w in wls])
                    if len(wls)
                    else table.specular(known)[0, 0]
                )
                total = s00 + albedo
                self.p_spec[n] = s00 / total if total > 0 else 0.0
        flat = self.p_cell.sum(axis=2)  # (k, nu) marginal in mu
        self.cdf_mu = np.concatenate([np.zeros((k, 1)), np.cumsum(flat, axis=1)], axis=1)
        self.cdf_mu /= self.cdf_mu[:, -1:]
        cond = self.p_cell / np.maximum(flat[:, :, None], 1e-300)
        self.cdf_phi = np.concatenate([np.zeros((k, nu, 1)), np.cumsum(cond, axis=2)], axis=2)
        self.cdf_phi /= self.cdf_phi[:, :, -1:]
        self.cell_area = area

    @staticmethod
    def _g(table, known, mu, dphi, wls):
        """``f11 mu`` for a sampled direction ``(mu, dphi)``, averaged over
        wavelengths ``wls``, with the known direction as the table's
        incident one (f11 is reciprocal)."""
        mu, dphi = np.broadcast_arrays(mu, dphi)
        st = np.sqrt(np.clip(1.0 - mu**2, 0.0, 1.0))
        phi = math.pi + dphi  # dphi_prop = phi_o - phi_i - 180 deg, phi_i = 0
        wo = np.stack([st * np.cos(phi), st * np.sin(phi), np.maximum(mu, 0.0)], axis=-1)
        wo[..., 2] = np.where(mu <= 0, 1e-9, wo[..., 2])
        if len(wls) == 0:
            f = table.eval(known, wo)[..., 0, 0]
        else:
            f = np.mean([table.eval(known, wo, w, clamp_wavelength=True)[..., 0, 0] for w in wls], axis=0)
        return np.clip(f, 0.0, None) * np.clip(mu, 0.0, None)

    def node(self, known: np.ndarray) -> np.ndarray:
        """Index of the polar node nearest to each known direction ``(n, 3)``."""
        theta = np.degrees(np.arctan2(np.hypot(known[:, 0], known[:, 1]), known[:, 2]))
        mid = (self.theta_nodes[1:] + self.theta_nodes[:-1]) / 2
        return np.searchsorted(mid, theta)

    def density(self, k, mu, adphi) -> np.ndarray:
        """The diffuse lobe's density per steradian (before the lobe choice)."""
        i = np.clip((mu * self.nu).astype(int), 0, self.nu - 1)
        j = np.clip((adphi / math.pi * self.nv).astype(int), 0, self.nv - 1)
        return self.p_cell[k, i, j] / self.cell_area

    def sample(self, k, u_mu, u_phi, sign):
        """Sampled ``(mu, dphi)`` for uniforms ``u_mu``, ``u_phi`` and a sign."""
        i = _pick(self.cdf_mu[k], u_mu)
        lo = self.cdf_mu[k, i]
        hi = self.cdf_mu[k, i + 1]
        f_mu = np.clip((u_mu - lo) / np.maximum(hi - lo, 1e-300), 0.0, 1.0)
        mu = (i + f_mu) / self.nu
        cdf = self.cdf_phi[k, i]
        j = _pick(cdf, u_phi)
        lo = np.take_along_axis(cdf, j[:, None], 1)[:, 0]
        hi = np.take_along_axis(cdf, j[:, None] + 1, 1)[:, 0]
        f_phi = np.clip((u_phi - lo) / np.maximum(hi - lo, 1e-300), 0.0, 1.0)
        dphi = (j + f_phi) / self.nv * math.pi
        return mu, sign * dphi


def _pick(cdf: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Per row, the cell ``i`` with ``cdf[i] <= u < cdf[i + 1]``, skipping
    empty cells."""
    cdf = np.atleast_2d(cdf)
    i = (cdf[:, 1:-1] <= u[:, None]).sum(axis=1)
    return np.clip(i, 0, cdf.shape[1] - 2)


def _unit(theta_deg: float, phi_deg: float) -> np.ndarray:
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    return np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)])


def _make_class(mi, dr):
    """The plugin class for the active Mitsuba variant."""
    variant = mi.variant()
    scalar = variant.startswith("scalar")

    def to_spectrum(m: np.ndarray):
        """Mueller matrices in mi.Spectrum's layout ``(4, 4, 4 wavelengths,
        n lanes)`` as mi.Spectrum."""
        return mi.Spectrum(m[..., 0] if scalar else m)

    def to_vec(a: np.ndarray):
        return mi.Vector3f(a[0]) if scalar else mi.Vector3f(np.ascontiguousarray(a.T))

    def to_float(a: np.ndarray):
        return mi.Float(float(a[0])) if scalar else mi.Float(np.ascontiguousarray(a, dtype=np.float32))

    def to_bool(a: np.ndarray):
        return mi.Bool(bool(a[0])) if scalar else mi.Bool(np.ascontiguousarray(a))

    def _width(*arrays) -> int:
        """Lanes of a call: the widest argument (Dr.Jit broadcasts width 1)."""
        return 1 if scalar else max(dr.width(a) for a in arrays)

    class PolbrdfBSDF(mi.BSDF):
        """polbrdf's table as a Mitsuba BSDF (module doc)."""

        def __init__(self, props):
            mi.BSDF.__init__(self, props)

            def has(key):
                return key in props

            if has("filename") == has("url"):
                raise ValueError('polbrdf: give exactly one of "filename" and "url"')
            token = props.get("token", None) if has("token") else None
            cache = props.get("cache_dir", None) if has("cache_dir") else None
            source = props.get("filename") if has("filename") else props.get("url")
            self.source = str(source)
            self.table = Table.load(self.source, cache_dir=cache, token=token)
            if self.table.metadata.get("theta_i_deg") is not None:
                raise ValueError(
                    f"polbrdf: {self.source} holds only some incident directions "
                    "(needs.theta_i_deg); a render needs them all"
                )
            if self.table.shape != (4, 4):
                raise ValueError(
                    f"polbrdf: {self.source} holds {self.table.shape[0]}x{self.table.shape[1]} "
                    "matrices (needs.stokes); a polarized render needs the full 4x4 table"
                )
            wl = self.table.wavelengths_nm
            self.wavelength_range = (float(wl[0]), float(wl[-1])) if len(wl) else None
            self.density = SamplingDensity(self.table)
            glossy = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide
            if self.table.has_specular:
                delta = mi.BSDFFlags.DeltaReflection | mi.BSDFFlags.FrontSide
                self.m_components = [delta, glossy]
                self.m_flags = delta | glossy
            else:
                self.m_components = [glossy]
                self.m_flags = glossy

        # -- helpers -------------------------------------------------------
        def _wavelengths(self, si, n):
            if self.wavelength_range is None:
                return None
            wl = np.asarray(si.wavelengths, dtype=float)
            wl = wl.reshape(4, -1) if wl.ndim > 1 else wl.reshape(4, 1)
            return np.broadcast_to(wl, (4, n)).T  # (n, 4)

        def _enabled(self, ctx, delta: bool) -> bool:
            if delta:
                return self.table.has_specular and ctx.is_enabled(mi.BSDFFlags.DeltaReflection, 0)
            index = 1 if self.table.has_specular else 0
            return ctx.is_enabled(mi.BSDFFlags.GlossyReflection, index)

        def _diffuse(self, light, view, wl, ok, wo):
            """``D f D cos`` in the meridian frames, float32 ``(4, 4, 4 wl,
            n)`` (mi.Spectrum's layout), 0 where not ``ok``; the cosine is of
            Mitsuba's ``wo``, the direction the integrator integrates over
            (the light in radiance mode, the viewer side in importance mode),
            as Mitsuba's BSDFs (``measured_polarized`` among them) do. The
            lookups, the V flip and the cosine run in Rust
            (``NativeTable.eval_mitsuba``)."""
            return self.table._native.eval_mitsuba(
                np.ascontiguousarray(light),
                np.ascontiguousarray(view),
                None if wl is None else np.ascontiguousarray(wl),
                np.ascontiguousarray(wo[:, 2]),
                np.ascontiguousarray(ok, dtype=bool),
            )

        def _to_mitsuba(self, m, light, view, ok):
            """Rotate ``(4, 4, 4, n)`` matrices from the meridian frames into
            Mitsuba's Stokes bases of the rays ``-light`` and ``view``; 0 where
            not ``ok`` (whose directions, e.g. the NaNs of inactive lanes,
            are replaced by the normal so that no NaN leaks out)."""
            normal = np.array([0.0, 0.0, 1.0])
            light = np.where(ok[:, None], light, normal)
            view = np.where(ok[:, None], view, normal)
            m = np.where(ok, m, np.float32(0.0))
            lv, vv = to_vec(light), to_vec(view)
            k_in = -lv
            return mi.mueller.rotate_mueller_basis(
                to_spectrum(m),
                k_in,
                to_vec(meridian_x(light)),
                mi.mueller.stokes_basis(k_in),
                vv,
                to_vec(meridian_x(view)),
                mi.mueller.stokes_basis(vv),
            )

        def _directions(self, ctx, si, wo, n):
            """(light, viewer) as ``(n, 3)``: radiance mode has the light in
            ``wo``; importance mode swaps them."""
            a = _columns(si.wi, n)
            b = _columns(wo, n)
            if ctx.mode == mi.TransportMode.Importance:
                return a, b
            return b, a

        def _pdf(self, known, sampled):
            """The pdf (per steradian) of sampling the unit vectors
            ``sampled`` given ``known``: |dphi| is the sampled azimuth's
            distance from the mirror side, wrapped to [0, pi]."""
            k = self.density.node(known)
            phi_k = np.arctan2(known[:, 1], known[:, 0])
            phi_s = np.arctan2(sampled[:, 1], sampled[:, 0])
            dphi = np.abs(np.remainder(phi_s - phi_k, 2.0 * math.pi) - math.pi)
            return (1.0 - self.density.p_spec[k]) * self.density.density(k, sampled[:, 2], dphi)

        # -- the BSDF interface --------------------------------------------
        def eval(self, ctx, si, wo, active=True):
            n = _width(si.wi, wo, active)
            light, view = self._directions(ctx, si, wo, n)
            ok = _lanes(active, n).astype(bool) & (light[:, 2] > 0) & (view[:, 2] > 0)
            if not self._enabled(ctx, False):
                ok[:] = False
            m = self._diffuse(light, view, self._wavelengths(si, n), ok, _columns(wo, n))
            return self._to_mitsuba(m, light, view, ok)

        def pdf(self, ctx, si, wo, active=True):
            # The density is of the sampled direction `wo` given `si.wi`,
            # in either transport mode.
            n = _width(si.wi, wo, active)
            known, sampled = _columns(si.wi, n), _columns(wo, n)
            ok = _lanes(active, n).astype(bool) & (known[:, 2] > 0) & (sampled[:, 2] > 0)
            p = np.zeros(n)
            if self._enabled(ctx, False) and ok.any():
                p[ok] = self._pdf(known[ok], sampled[ok])
            return to_float(p)

        def eval_pdf(self, ctx, si, wo, active=True):
            return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

        def sample(self, ctx, si, sample1, sample2, active=True):
            n = _width(si.wi, sample1, sample2, active)
            known = _columns(si.wi, n)
            u1 = _lanes(np.asarray(sample1, dtype=float), n).astype(float)
            u2 = np.stack([_lanes(np.asarray(c, dtype=float), n) for c in (sample2.x, sample2.y)])
            ok = _lanes(active, n).astype(bool) & (known[:, 2] > 0)
            k = self.density.node(known)
            want_delta = self._enabled(ctx, True)
            want_diffuse = self._enabled(ctx, False)
            if want_diffuse:
                p_spec = self.density.p_spec[k] if want_delta else np.zeros(n)
            else:
                p_spec = np.full(n, 1.0 if want_delta else 0.0)
            delta = ok & (u1 < p_spec)
            diffuse = ok & ~delta & want_diffuse
            rest = np.clip((u1 - p_spec) / np.maximum(1.0 - p_spec, 1e-300), 0.0, 1.0)
            sign = np.where(rest < 0.5, -1.0, 1.0)
            mu, dphi = self.density.sample(k, u2[0], u2[1], sign)
            phi = np.arctan2(known[:, 1], known[:, 0]) + math.pi + dphi
            st = np.sqrt(np.clip(1.0 - mu**2, 0.0, 1.0))
            sampled = np.stack([st * np.cos(phi), st * np.sin(phi), mu], axis=1)
            mirror = known * np.array([-1.0, -1.0, 1.0])
            sampled = np.where(delta[:, None], mirror, sampled)
            diffuse &= mu > 0
            # Pdf (solid angle for the diffuse lobe, discrete for the delta).
            pdf = np.zeros(n)
            if diffuse.any():
                pdf[diffuse] = self._pdf(known[diffuse], sampled[diffuse])
            pdf[delta] = p_spec[delta]
            # Weight: f cos / pdf in the ray bases (radiance: light = sampled).
            if ctx.mode == mi.TransportMode.Importance:
                light, view = known, sampled
            else:
                light, view = sampled, known
            wl = self._wavelengths(si, n)
            m = self._diffuse(light, view, wl, diffuse, sampled)
            if delta.any():
                idx = np.nonzero(delta)[0]
                w = None if wl is None else wl[idx].reshape(-1)
                s = self.table.specular(np.repeat(light[idx], 4, axis=0), w, clamp_wavelength=True)
                s = s.reshape(len(idx), 4, 4, 4) * _D_V[:, None] * _D_V[None, :]
                m[:, :, :, idx] = np.transpose(s, (2, 3, 1, 0))  # (row, col, wl, lane)
            live = (diffuse | delta) & (pdf > 0)
            m *= np.where(live, 1.0 / np.where(live, pdf, 1.0), 0.0).astype(np.float32)
            weight = self._to_mitsuba(m, light, view, live)

            bs = dr.zeros(mi.BSDFSample3f) if scalar else dr.zeros(mi.BSDFSample3f, n)
            bs.wo = to_vec(sampled)
            bs.pdf = to_float(pdf)
            bs.eta = 1.0
            lobe_delta = int(mi.BSDFFlags.DeltaReflection)
            lobe_glossy = int(mi.BSDFFlags.GlossyReflection)
            types = np.where(delta, lobe_delta, lobe_glossy).astype(np.uint32)
            comps = np.where(delta | ~self.table.has_specular, 0, 1).astype(np.uint32)
            bs.sampled_type = mi.UInt32(int(types[0])) if scalar else mi.UInt32(types)
            bs.sampled_component = mi.UInt32(int(comps[0])) if scalar else mi.UInt32(comps)
            return bs, dr.select(to_bool(live), weight, 0.0)

        def traverse(self, callback):
            pass

        def parameters_changed(self, keys):
            pass

        def to_string(self):
            return f"PolbrdfBSDF[source={self.source!r}, table={self.table!r}]"

    return PolbrdfBSDF


def register(name: str = "polbrdf", set_jit_flags: bool = True) -> None:
    """Register the plugin ``name`` for the active Mitsuba variant (a
    ``*_spectral_polarized`` one). Call it after ``mi.set_variant``; again
    after switching variants."""
    import drjit as dr
    import mitsuba as mi

    variant = mi.variant()
    if not variant or not variant.endswith("spectral_polarized"):
        raise ValueError(
            f"polbrdf.mitsuba needs a *_spectral_polarized variant (e.g. "
            f"scalar_spectral_polarized, llvm_ad_spectral_polarized), not {variant!r}"
        )
    if set_jit_flags and not variant.startswith("scalar"):
        dr.set_flag(dr.JitFlag.SymbolicLoops, False)
        dr.set_flag(dr.JitFlag.SymbolicCalls, False)
    cls = _make_class(mi, dr)
    mi.register_bsdf(name, lambda props: cls(props))


__all__ = ["register", "SamplingDensity", "meridian_x"]
