"""polbrdf: polarized BRDFs of paints, coatings and powders from first principles.

Mie theory for each particle population, the vector radiative transfer
equation by discrete ordinates over a stack of layers on a base, and the
4x4 Mueller-matrix BRDF for every direction pair. This package is the Rust
library behind the ``polbrdf`` command line and service (docs/python.md);
every number it returns is the one ``polbrdf mie``, ``polbrdf solve`` and
``polbrdf eval`` return for the same inputs.

Conventions (docs/conventions.md): directions are unit vectors
``w = (sin t cos p, sin t sin p, cos t)`` pointing *away* from the surface
(z = outward normal); light arrives along ``-wi`` and leaves along ``wo``.
Mueller matrices are in 1/sr, row = outgoing Stokes component, in the
meridian frames of conventions section 5 (incident ``x = (cos ti cos pi,
cos ti sin pi, -sin ti)``, outgoing ``x = (cos to cos po, cos to sin po,
-sin to)``), V positive for right-handed circular polarization as seen by
the receiver looking at the source (IAU / Hovenier).

>>> import polbrdf
>>> table = polbrdf.solve({"wavelengths_nm": [550], "layers": [...], "base": {"kind": "black"}})
>>> table.eval(wi, wo, wavelength_nm=550.0).shape   # wi, wo: (..., 3)
(..., 4, 4)
"""

from __future__ import annotations

import json
import math
import os
from typing import Any, Mapping, Optional, Union

import numpy as np

from . import _native
from ._native import FetchError, PolbrdfError, QueryError, SpecError
from .client import Client

__all__ = [
    "Client",
    "FetchError",
    "PolbrdfError",
    "QueryError",
    "SpecError",
    "Table",
    "direction",
    "mie",
    "solve",
]

__version__ = _native.__version__

SpecLike = Union[str, bytes, Mapping[str, Any]]


def _spec_json(spec: SpecLike) -> str:
    """A spec as JSON text: a mapping, JSON text, or a path to a JSON file."""
    if isinstance(spec, Mapping):
        return json.dumps(spec)
    if isinstance(spec, bytes):
        return spec.decode("utf-8")
    if isinstance(spec, (str, os.PathLike)):
        text = os.fspath(spec)
        if text.lstrip().startswith("{"):
            return text
        with open(text, encoding="utf-8") as f:
            return f.read()
    raise TypeError(f"a spec is a dict, JSON text or a file path, not {type(spec).__name__}")


def _max_streams(max_streams: Optional[int]) -> int:
    return _native.default_max_streams() if max_streams is None else int(max_streams)


def direction(theta_deg, phi_deg) -> np.ndarray:
    """Unit vectors ``(sin t cos p, sin t sin p, cos t)`` of graphics angles in
    degrees (conventions section 5), broadcast: shape ``(..., 3)``."""
    t = np.radians(np.asarray(theta_deg, dtype=float))
    p = np.radians(np.asarray(phi_deg, dtype=float))
    t, p = np.broadcast_arrays(t, p)
    return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1)


def mie(**options: Any) -> dict:
    """Mie scattering of one particle population: ``polbrdf mie`` as a dict.

    Keyword arguments are the command's flags with underscores:
    ``polbrdf.mie(material="TiO2", wavelength_nm=550, radius_um=0.2)`` runs
    ``polbrdf mie --material TiO2 --wavelength-nm 550 --radius-um 0.2``. A
    list becomes a comma-separated value, ``True`` a bare flag. The result
    holds the efficiencies, asymmetry parameter and expansion coefficients
    (docs/spec.md, the Mie report); radius in micrometres, wavelength in nm.
    ``spec=`` (a dict or a file path) reports every layer of a spec instead.
    """
    args = []
    spec_file = None
    if isinstance(options.get("spec"), Mapping):
        import tempfile

        with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
            json.dump(options["spec"], f)
        spec_file = options["spec"] = f.name
    try:
        return _mie(args, options)
    finally:
        if spec_file is not None:
            os.unlink(spec_file)


def _mie(args: list, options: Mapping[str, Any]) -> dict:
    for key, value in options.items():
        if value is None or value is False:
            continue
        flag = "--" + key.replace("_", "-")
        if value is True:
            args.append(flag)
            continue
        if isinstance(value, (list, tuple, np.ndarray)):
            value = ",".join(_number(v) for v in value)
        elif isinstance(value, (int, float, np.floating, np.integer)):
            value = _number(value)
        args.append(f"{flag}={value}")  # `=`: a value may start with '-'.
    return json.loads(_native.mie(args))


def _number(v: Any) -> str:
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    return str(v)


def solve(spec: SpecLike, points=None, max_streams: Optional[int] = None):
    """Solve a material spec (docs/spec.md).

    Without ``points``: the BRDF table the spec requests (its ``needs``, on
    its grid), as a :class:`Table`. With ``points``, an array of shape
    ``(n, 4)`` of graphics angles in degrees (``theta_i_deg, phi_i_deg,
    theta_o_deg, phi_o_deg``), the direct solve at those pairs: a dict with
    ``wavelengths_nm`` (``W`` values, ``None`` for a wavelength-free spec),
    ``mueller`` of shape ``(W, n, 4, 4)`` (1/sr), ``specular`` of shape
    ``(W, n, 4, 4)`` (NaN where the pair is not a mirror pair) and
    ``results``, the full ``polbrdf solve --points`` document (error
    estimates, streams, timings).

    The GIL is released while solving. A spec error raises
    :class:`SpecError` with ``path`` set (``layers[0].optical_thickness``).
    """
    text = _spec_json(spec)
    cap = _max_streams(max_streams)
    if points is None:
        return Table(_native.build_table(text, cap))
    pts = np.ascontiguousarray(np.asarray(points, dtype=float))
    if pts.ndim == 1:
        pts = pts.reshape(1, -1)
    if pts.ndim != 2 or pts.shape[1] != 4:
        raise QueryError(f"points must have shape (n, 4), got {np.shape(points)}")
    doc = json.loads(_native.solve_points(text, pts, cap))
    results = doc["results"]
    n = pts.shape[0]
    mueller = np.zeros((len(results), n, 4, 4))
    specular = np.full((len(results), n, 4, 4), np.nan)
    for w, r in enumerate(results):
        for k, p in enumerate(r["points"]):
            mueller[w, k] = _square(p["mueller"])
            if p.get("specular") is not None:
                specular[w, k] = _square(p["specular"])
    return {
        "wavelengths_nm": [r.get("wavelength_nm") for r in results],
        "mueller": mueller,
        "specular": specular,
        "results": results,
    }


def _square(m) -> np.ndarray:
    """A Mueller block (4x4, 4x1 or 1x1 by ``needs.stokes``) as 4x4, zeros
    outside."""
    a = np.atleast_2d(np.asarray(m, dtype=float))
    out = np.zeros((4, 4))
    out[: a.shape[0], : a.shape[1]] = a
    return out


class Table:
    """A polbrdf BRDF table (docs/table-format.md): per wavelength, the
    Fourier coefficients in azimuth at polar nodes, with the specular term of
    a mirror base.

    Evaluation is exact in azimuth (the Fourier sum), interpolated in the
    polar cosines as ``polbrdf eval`` does, and linear in wavelength.
    """

    def __init__(self, native: "_native.NativeTable", outcome: Optional[str] = None):
        self._native = native
        #: How a fetch through the render-node cache was answered (``hit``,
        #: ``miss``, ...), ``None`` for a file or a direct download.
        self.outcome = outcome

    # -- construction -----------------------------------------------------
    @classmethod
    def load(
        cls,
        source: Union[str, os.PathLike],
        cache_dir: Union[str, os.PathLike, None] = None,
        token: Optional[str] = None,
        revalidate: bool = False,
        wait_s: Optional[float] = None,
    ) -> "Table":
        """A table from a file (``.pbrdf``, as ``polbrdf export`` writes) or a
        service result URL (``http://host:8080/v1/brdfs/ID``).

        A URL goes through the render-node cache in ``cache_dir`` (default:
        the ``POLBRDF_CACHE_DIR`` environment variable, docs/deploy.md), so
        a table is downloaded once per machine and verified by its digest;
        without a cache directory it is downloaded and verified each time.
        ``token`` is the service's bearer token; ``wait_s`` waits that long
        for a queued or running job.
        """
        src = os.fspath(source)
        if cache_dir is None:
            cache_dir = os.environ.get("POLBRDF_CACHE_DIR") or None
        native, outcome = _native.load_table(
            src,
            None if cache_dir is None else os.fspath(cache_dir),
            token,
            revalidate,
            wait_s,
        )
        return cls(native, outcome)

    @classmethod
    def from_bytes(cls, data: bytes) -> "Table":
        """A table from the bytes of a table file (``GET /v1/brdfs/ID/table``)."""
        return cls(_native.NativeTable.from_bytes(bytes(data)))

    def to_bytes(self) -> bytes:
        """The table file's bytes (f64, lossless)."""
        return self._native.to_bytes()

    def save(self, path: Union[str, os.PathLike]) -> None:
        """Write the table file (f64) to ``path`` atomically."""
        self._native.save(os.fspath(path))

    def __reduce__(self):
        return (Table.from_bytes, (self.to_bytes(),))

    # -- description ------------------------------------------------------
    @property
    def metadata(self) -> dict:
        """The table's metadata (docs/table-format.md): the canonical spec,
        per wavelength the streams, Fourier orders, timings and error
        estimate."""
        return json.loads(self._native.metadata_json())

    @property
    def wavelengths_nm(self) -> np.ndarray:
        """The table's wavelengths (nm), increasing; empty if wavelength-free."""
        return np.asarray(self._native.wavelengths_nm())

    @property
    def theta_deg(self) -> np.ndarray:
        """The polar nodes (degrees) of the table's grid."""
        return np.asarray(self._native.theta_deg())

    @property
    def shape(self) -> tuple:
        """Rows and columns the table holds: ``(4, 4)``, ``(4, 1)`` for
        ``needs.stokes: "unpolarized_in"``, ``(1, 1)`` for ``"intensity"``
        (the other elements evaluate to 0)."""
        return tuple(self._native.shape())

    @property
    def has_specular(self) -> bool:
        """Does the table hold the specular term of a mirror base (or of a
        smooth top interface)?"""
        return self._native.has_specular()

    def __repr__(self) -> str:
        wl = self.wavelengths_nm
        wls = ", ".join(f"{w:g}" for w in wl) if len(wl) else "none"
        return (
            f"<polbrdf.Table {len(self.theta_deg)} polar nodes, wavelengths_nm [{wls}],"
            f" {self.shape[0]}x{self.shape[1]}{', specular' if self.has_specular else ''}>"
        )

    # -- evaluation -------------------------------------------------------
    def _wavelengths(self, wavelength_nm, shape) -> Optional[np.ndarray]:
        if wavelength_nm is None:
            return None
        wl = np.broadcast_to(np.asarray(wavelength_nm, dtype=float), shape)
        return np.ascontiguousarray(wl.reshape(-1))

    def eval(self, wi, wo, wavelength_nm=None, clamp_wavelength: bool = False) -> np.ndarray:
        """The diffuse Mueller BRDF (1/sr) at direction pairs.

        ``wi``, ``wo``: arrays of shape ``(..., 3)`` of directions pointing
        away from the surface (need not be normalised; broadcast against each
        other). ``wavelength_nm``: scalar or array broadcast against the
        directions' leading shape; may be omitted for a one-wavelength table;
        outside the table's range it is an error unless ``clamp_wavelength``.
        Returns shape ``(..., 4, 4)``. The specular delta of a mirror base is
        not included (see :meth:`specular`).
        """
        wi = np.asarray(wi, dtype=float)
        wo = np.asarray(wo, dtype=float)
        if wi.shape[-1:] != (3,) or wo.shape[-1:] != (3,):
            raise QueryError(f"wi and wo must have shape (..., 3), got {wi.shape} and {wo.shape}")
        lead = np.broadcast_shapes(wi.shape[:-1], wo.shape[:-1])
        if wavelength_nm is not None:
            lead = np.broadcast_shapes(lead, np.shape(wavelength_nm))
        a = np.ascontiguousarray(np.broadcast_to(wi, lead + (3,)).reshape(-1, 3))
        b = np.ascontiguousarray(np.broadcast_to(wo, lead + (3,)).reshape(-1, 3))
        m = self._native.eval_flat(a, b, self._wavelengths(wavelength_nm, lead), clamp_wavelength)
        return m.reshape(lead + (4, 4))

    def eval_angles(
        self,
        theta_i_deg,
        phi_i_deg,
        theta_o_deg,
        phi_o_deg,
        wavelength_nm=None,
        clamp_wavelength: bool = False,
    ) -> np.ndarray:
        """The diffuse Mueller BRDF (1/sr) at graphics angles in degrees
        (``theta`` in ``[0, 90]``, ``phi`` in ``[-360, 360]``), broadcast
        against each other and ``wavelength_nm``: shape ``(..., 4, 4)``.
        The same numbers as ``polbrdf eval`` and ``GET /v1/brdfs/ID/eval``."""
        parts = np.broadcast_arrays(
            *(np.asarray(x, dtype=float) for x in (theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg)),
            *(() if wavelength_nm is None else (np.asarray(wavelength_nm, dtype=float),)),
        )
        lead = parts[0].shape
        angles = np.ascontiguousarray(np.stack([p.reshape(-1) for p in parts[:4]], axis=-1))
        wl = None if wavelength_nm is None else np.ascontiguousarray(parts[4].reshape(-1))
        m = self._native.eval_angles_flat(angles, wl, clamp_wavelength)
        return m.reshape(lead + (4, 4))

    def specular(self, wi, wavelength_nm=None, clamp_wavelength: bool = False) -> Optional[np.ndarray]:
        """The specular matrix ``S`` of a mirror base (conventions section 6:
        the reflected beam around the mirror direction carries ``S F`` of an
        incident beam ``F``), for incident directions ``wi`` of shape
        ``(..., 3)``: shape ``(..., 4, 4)``, in the meridian frames of
        ``wi`` and of its mirror direction; ``None`` without a mirror base."""
        wi = np.asarray(wi, dtype=float)
        if wi.shape[-1:] != (3,):
            raise QueryError(f"wi must have shape (..., 3), got {wi.shape}")
        lead = wi.shape[:-1]
        if wavelength_nm is not None:
            lead = np.broadcast_shapes(lead, np.shape(wavelength_nm))
        a = np.ascontiguousarray(np.broadcast_to(wi, lead + (3,)).reshape(-1, 3))
        s = self._native.specular_flat(a, self._wavelengths(wavelength_nm, lead), clamp_wavelength)
        return None if s is None else s.reshape(lead + (4, 4))

    def albedo(self, wi, wavelength_nm=None, n_theta: int = 64, n_phi: int = 64) -> np.ndarray:
        """Directional-hemispherical reflectance of unpolarized light (the
        integral of ``f11 cos(to)`` over the outgoing hemisphere, plus the
        specular ``S00``) for incident directions ``wi`` ``(..., 3)``, by
        Gauss-Legendre quadrature in ``cos(to)`` and the trapezoid rule in
        azimuth."""
        wi = np.asarray(wi, dtype=float)
        lead = wi.shape[:-1]
        x, w = np.polynomial.legendre.leggauss(n_theta)
        mu = 0.5 * (x + 1.0)
        wmu = 0.5 * w
        phi = np.linspace(0.0, 2.0 * math.pi, n_phi, endpoint=False)
        s = np.sqrt(np.clip(1.0 - mu**2, 0.0, None))
        wo = np.stack(
            [s[:, None] * np.cos(phi)[None, :], s[:, None] * np.sin(phi)[None, :], np.broadcast_to(mu[:, None], (n_theta, n_phi))],
            axis=-1,
        )
        flat_wi = wi.reshape(-1, 3)
        out = np.empty(flat_wi.shape[0])
        wl = None if wavelength_nm is None else np.broadcast_to(np.asarray(wavelength_nm, float), lead).reshape(-1)
        for k, d in enumerate(flat_wi):
            f = self.eval(d[None, None, :], wo, None if wl is None else wl[k])[..., 0, 0]
            out[k] = np.sum(f * (mu * wmu)[:, None]) * (2.0 * math.pi / n_phi)
            if self.has_specular:
                out[k] += self.specular(d, None if wl is None else wl[k])[0, 0]
        return out.reshape(lead)
