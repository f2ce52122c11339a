//! The binary table file, version 6 (docs/table-format.md, the normative
//! description). Little-endian throughout.
//!
//! ```text
//! header (56 bytes)
//!   0  8  magic  b"PBRDFTAB"
//!   8  4  u32    format version (6; versions 4 and 5 are read too)
//!  12  4  u32    data type of the coefficients: 1 = f32, 2 = f64
//!  16  8  u64    payload length in bytes (everything after the header)
//!  24 32  SHA-256 of header bytes 0..24 followed by the payload
//! payload
//!   u64 L, L bytes of UTF-8 JSON metadata
//!   u32 W (wavelengths), u32 N (polar nodes), u32 ns (1 or 4), u32 flags
//!       (bit 0: specular matrices present; bit 1: correction records;
//!        bit 2: column 0 only, C = 1 (else C = ns); bit 3: incident
//!        nodes listed; bit 4: rough surface records, version 6)
//!   f64[N] θ nodes (deg), f64[N] μ nodes, f64[W] wavelengths (nm; NaN: none)
//!   u32[W] M_w (Fourier orders per wavelength)
//!   if flag bit 3: u32 K, u32[K] the grid nodes held on the incident axis
//!       (strictly increasing, < N); else K = N, all of them
//!   per wavelength w: data[M_w][N (out)][K (in)][ns][C]  f^m(μ_o, μ_i)
//!                     then, if flag bit 0: data[K (in)][R][R]  specular S,
//!                     R = 4 (R × R = ns × C with bit 2)
//!                     then, if flag bit 1: a correction record (below)
//!                     then, if flag bit 4: a surface record (below)
//! correction record (always f64; the single-scattering correction T3)
//!   u32 present (0/1); if 1:
//!   u32 polarized (0/1), u32 K (layers), u32 streams of the solve,
//!   f64 mirror depth τ', f64 n1, f64 n2, f64 k2  (all NaN: no mirror)
//!   f64 binder index of a smooth top interface (NaN: none; not in version 4)
//!   per layer: f64 ω, τ, τ_top, ω', τ', τ'_top (τ may be +inf), f64[4]
//!     removed forward fractions (f, f₂₃, f₂₃, f₄), then the
//!     full and the truncated expansion, each as six series
//!     (β, α, ζ, δ, γ, ε), each a u32 length and that many f64
//! surface record (always f64; a rough top interface's own reflection T4)
//!   u32 present (0/1); if 1: f64 ambient index, f64 n, f64 k, f64 alpha
//! ```
//!
//! Readers reject a short file, a bad magic, an unknown version or data
//! type, a payload length that disagrees with the file size and a SHA-256
//! mismatch, each with its own message, before parsing anything else.

use super::BrdfError;
use super::grid::PolarGrid;
use super::table::{Metadata, StoredCorrection, Table, WavelengthTable};
use crate::digest::{self, hex};
use crate::material::needs::StokesNeed;
use crate::physics::RefractiveIndex;
use crate::physics::expansion::GreekCoefficients;
use crate::physics::microfacet::RoughSurface;
use crate::physics::stokes::Mueller;
use crate::solver::truncation::CorrectionLayer;

/// The first 8 bytes of every table file.
pub const MAGIC: [u8; 8] = *b"PBRDFTAB";

/// The format version this build writes; it reads it and
/// [`OLDEST_READ_VERSION`] onwards.
pub const VERSION: u32 = 6;

/// The version a table is written in: the oldest that holds it, so that
/// tables without a top interface keep the bytes (and stored rows their
/// media type) of every version-4 writer: 6 when it carries a rough
/// surface record, 5 when a correction record carries an interface index,
/// else 4.
pub fn version_of(table: &Table) -> u32 {
    if table.wavelengths.iter().any(|w| w.surface.is_some()) {
        return VERSION;
    }
    let interface = table.wavelengths.iter().any(|w| {
        w.correction
            .as_ref()
            .is_some_and(|c| c.interface_index.is_some())
    });
    if interface { 5 } else { OLDEST_READ_VERSION }
}

/// The oldest format version this build reads: version 4 lacks the
/// interface index of the correction record (no top interface).
pub const OLDEST_READ_VERSION: u32 = 4;

/// Header size in bytes.
pub const HEADER_LEN: usize = 56;

/// Storage type of the coefficients (axes are always f64).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DataType {
    /// IEEE single precision (relative rounding 6e-8, far below the
    /// interpolation error; half the size).
    F32,
    /// IEEE double precision (lossless).
    F64,
}

impl DataType {
    fn code(self) -> u32 {
        match self {
            DataType::F32 => 1,
            DataType::F64 => 2,
        }
    }
    fn size(self) -> usize {
        match self {
            DataType::F32 => 4,
            DataType::F64 => 8,
        }
    }
}

fn fmt_err(msg: impl Into<String>) -> BrdfError {
    BrdfError::Format(msg.into())
}

/// The header checksum: SHA-256 of the header's first 24 bytes and the
/// payload (docs/table-format.md).
fn checksum(header_start: &[u8], payload: &[u8]) -> [u8; 32] {
    digest::sha256_of(&[header_start, payload])
}

/// Serialise a table (docs/table-format.md).
pub fn to_bytes(table: &Table, dtype: DataType) -> Result<Vec<u8>, BrdfError> {
    let n = table.grid.len();
    let first = table.wavelengths.first();
    let ns = first.map_or(4, |w| w.ns);
    let cols = first.map_or(ns, |w| w.cols);
    let incident: Vec<usize> = first.map_or_else(|| (0..n).collect(), |w| w.incident.clone());
    let has_spec = table.wavelengths.iter().any(|w| w.specular.is_some());
    let has_corr = table.wavelengths.iter().any(|w| w.correction.is_some());
    let has_surface = table.wavelengths.iter().any(|w| w.surface.is_some());
    for w in &table.wavelengths {
        if w.ns != ns
            || w.cols != cols
            || w.incident != incident
            || w.nodes != n
            || w.specular.is_some() != has_spec
        {
            return Err(fmt_err(
                "inconsistent wavelength blocks (Stokes components, nodes or specular)",
            ));
        }
        if w.f.len() != w.orders * n * incident.len() * ns * cols {
            return Err(fmt_err("coefficient array has the wrong length"));
        }
    }
    let column_only = cols != ns || table.metadata.stokes != StokesNeed::Full;
    if column_only && cols != 1 {
        return Err(fmt_err("a reduced table holds one Mueller column"));
    }
    let listed = incident.len() != n;
    // The specular block: 4 × 4 as version 4 always had, or ns × 1.
    let (sr, sc) = if column_only { (ns, 1) } else { (4, 4) };
    let meta = serde_json::to_vec(&table.metadata).map_err(|e| fmt_err(e.to_string()))?;
    let mut p = Vec::new();
    p.extend_from_slice(&(meta.len() as u64).to_le_bytes());
    p.extend_from_slice(&meta);
    for x in [
        table.wavelengths.len() as u32,
        n as u32,
        ns as u32,
        u32::from(has_spec)
            | (u32::from(has_corr) << 1)
            | (u32::from(column_only) << 2)
            | (u32::from(listed) << 3)
            | (u32::from(has_surface) << 4),
    ] {
        p.extend_from_slice(&x.to_le_bytes());
    }
    for x in table.grid.theta_deg.iter().chain(&table.grid.mu) {
        p.extend_from_slice(&x.to_le_bytes());
    }
    for w in &table.wavelengths {
        p.extend_from_slice(&w.wavelength_nm.unwrap_or(f64::NAN).to_le_bytes());
    }
    for w in &table.wavelengths {
        p.extend_from_slice(&(w.orders as u32).to_le_bytes());
    }
    if listed {
        p.extend_from_slice(&(incident.len() as u32).to_le_bytes());
        for &i in &incident {
            p.extend_from_slice(&(i as u32).to_le_bytes());
        }
    }
    let put = |p: &mut Vec<u8>, x: f64| match dtype {
        DataType::F32 => p.extend_from_slice(&(x as f32).to_le_bytes()),
        DataType::F64 => p.extend_from_slice(&x.to_le_bytes()),
    };
    for w in &table.wavelengths {
        for &x in &w.f {
            put(&mut p, x);
        }
        if let Some(s) = &w.specular {
            for m in s {
                for row in &m[..sr] {
                    for &x in &row[..sc] {
                        put(&mut p, x);
                    }
                }
            }
        }
        if has_corr {
            put_correction(&mut p, w.correction.as_ref(), version_of(table));
        }
        if has_surface {
            put_surface(&mut p, w.surface.as_ref());
        }
    }
    let mut out = Vec::with_capacity(HEADER_LEN + p.len());
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&version_of(table).to_le_bytes());
    out.extend_from_slice(&dtype.code().to_le_bytes());
    out.extend_from_slice(&(p.len() as u64).to_le_bytes());
    let sha = checksum(&out[..24], &p);
    out.extend_from_slice(&sha);
    out.extend_from_slice(&p);
    Ok(out)
}

/// The surface record of one wavelength (module doc).
fn put_surface(p: &mut Vec<u8>, s: Option<&RoughSurface>) {
    let Some(s) = s else {
        p.extend_from_slice(&0u32.to_le_bytes());
        return;
    };
    p.extend_from_slice(&1u32.to_le_bytes());
    for x in [s.ambient, s.index.n, s.index.k, s.alpha] {
        p.extend_from_slice(&x.to_le_bytes());
    }
}

/// Read a surface record (module doc), checked as a spec's would be.
fn get_surface(c: &mut Cursor) -> Result<Option<RoughSurface>, BrdfError> {
    match c.u32("surface flag")? {
        0 => return Ok(None),
        1 => {}
        f => return Err(fmt_err(format!("malformed table: surface flag {f}"))),
    }
    let v = c.f64s(4, "surface record")?;
    let index = RefractiveIndex { n: v[1], k: v[2] };
    RoughSurface::new(v[0], index, v[3])
        .map(Some)
        .map_err(|e| fmt_err(format!("malformed table: surface record: {e}")))
}

/// The correction record of one wavelength (module doc).
fn put_correction(p: &mut Vec<u8>, c: Option<&StoredCorrection>, version: u32) {
    let Some(c) = c else {
        p.extend_from_slice(&0u32.to_le_bytes());
        return;
    };
    let corr = &c.correction;
    for x in [
        1,
        u32::from(corr.polarized),
        corr.layers.len() as u32,
        corr.streams as u32,
    ] {
        p.extend_from_slice(&x.to_le_bytes());
    }
    let depth = corr.mirror.as_ref().map_or(f64::NAN, |m| m.1);
    let (n1, n2, k2) = c
        .mirror_indices
        .map_or((f64::NAN, f64::NAN, f64::NAN), |(n1, n2)| (n1, n2.n, n2.k));
    for x in [depth, n1, n2, k2] {
        p.extend_from_slice(&x.to_le_bytes());
    }
    if version >= 5 {
        p.extend_from_slice(&c.interface_index.unwrap_or(f64::NAN).to_le_bytes());
    }
    for l in &corr.layers {
        for x in [l.omega, l.tau, l.tau_top, l.omega_t, l.tau_t, l.tau_top_t] {
            p.extend_from_slice(&x.to_le_bytes());
        }
        for x in l.fx {
            p.extend_from_slice(&x.to_le_bytes());
        }
        for g in [&l.coef, &l.coef_t] {
            for series in [&g.beta, &g.alpha, &g.zeta, &g.delta, &g.gamma, &g.epsilon] {
                p.extend_from_slice(&(series.len() as u32).to_le_bytes());
                for x in series.iter() {
                    p.extend_from_slice(&x.to_le_bytes());
                }
            }
        }
    }
}

/// Read a correction record (module doc).
fn get_correction(c: &mut Cursor, version: u32) -> Result<Option<StoredCorrection>, BrdfError> {
    match c.u32("correction flag")? {
        0 => return Ok(None),
        1 => {}
        x => {
            return Err(fmt_err(format!("malformed table: correction flag {x}")));
        }
    }
    let polarized = match c.u32("correction polarization")? {
        0 => false,
        1 => true,
        x => {
            return Err(fmt_err(format!(
                "malformed table: correction polarization {x}"
            )));
        }
    };
    let k = c.u32("correction layers")? as usize;
    let streams = c.u32("correction streams")? as usize;
    let m = c.f64s(4, "correction mirror")?;
    let mirror = if m.iter().all(|x| x.is_nan()) {
        None
    } else if m.iter().all(|x| x.is_finite()) && m[0] >= 0.0 && m[1] > 0.0 {
        Some((m[0], m[1], RefractiveIndex::new(m[2], m[3])))
    } else {
        return Err(fmt_err(format!("malformed table: correction mirror {m:?}")));
    };
    let interface_index = match version {
        4 => None,
        _ => match c.f64s(1, "correction interface index")?[0] {
            x if x.is_nan() => None,
            x if x.is_finite() && x >= 1.0 => Some(x),
            x => {
                return Err(fmt_err(format!(
                    "malformed table: correction interface index {x}"
                )));
            }
        },
    };
    let mut layers = Vec::with_capacity(k.min(1 << 16));
    for _ in 0..k {
        let v = c.f64s(6, "correction layer")?;
        // Albedos and depths finite and ≥ 0; thicknesses may be +inf.
        if v.iter().any(|x| x.is_nan() || *x < 0.0)
            || [v[0], v[2], v[3], v[5]].iter().any(|x| !x.is_finite())
        {
            return Err(fmt_err(format!("malformed table: correction layer {v:?}")));
        }
        let f = c.f64s(4, "correction forward fractions")?;
        if f.iter().any(|x| !(-1.0..=1.0).contains(x)) || !(0.0..1.0).contains(&f[0]) {
            return Err(fmt_err(format!(
                "malformed table: correction forward fractions {f:?}"
            )));
        }
        let mut coefs = Vec::with_capacity(2);
        for _ in 0..2 {
            let mut series = Vec::with_capacity(6);
            for _ in 0..6 {
                let len = c.u32("expansion length")? as usize;
                let s = c.f64s(len, "expansion")?;
                if s.iter().any(|x| !x.is_finite()) {
                    return Err(fmt_err(
                        "malformed table: a correction expansion holds a non-finite value",
                    ));
                }
                series.push(s);
            }
            let mut it = series.into_iter();
            let mut next = || it.next().unwrap();
            coefs.push(GreekCoefficients {
                beta: next(),
                alpha: next(),
                zeta: next(),
                delta: next(),
                gamma: next(),
                epsilon: next(),
            });
        }
        let coef_t = coefs.pop().unwrap();
        let coef = coefs.pop().unwrap();
        layers.push(CorrectionLayer {
            omega: v[0],
            tau: v[1],
            tau_top: v[2],
            coef,
            omega_t: v[3],
            tau_t: v[4],
            tau_top_t: v[5],
            coef_t,
            fx: [f[0], f[1], f[2], f[3]],
        });
    }
    Ok(Some(StoredCorrection::from_parts(
        layers,
        polarized,
        streams,
        mirror,
        interface_index,
    )))
}

/// A bounds-checked little-endian reader over the payload.
struct Cursor<'a> {
    b: &'a [u8],
    at: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], BrdfError> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.b.len())
            .ok_or_else(|| {
                fmt_err(format!(
                    "malformed table: {what} runs past the end of the payload"
                ))
            })?;
        let s = &self.b[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn u32(&mut self, what: &str) -> Result<u32, BrdfError> {
        Ok(u32::from_le_bytes(self.take(4, what)?.try_into().unwrap()))
    }
    fn u64(&mut self, what: &str) -> Result<u64, BrdfError> {
        Ok(u64::from_le_bytes(self.take(8, what)?.try_into().unwrap()))
    }
    fn f64s(&mut self, n: usize, what: &str) -> Result<Vec<f64>, BrdfError> {
        let bytes = self.take(
            n.checked_mul(8).ok_or_else(|| fmt_err("size overflow"))?,
            what,
        )?;
        Ok(bytes
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
            .collect())
    }
    fn data(&mut self, n: usize, dtype: DataType, what: &str) -> Result<Vec<f64>, BrdfError> {
        let len = n
            .checked_mul(dtype.size())
            .ok_or_else(|| fmt_err("size overflow"))?;
        let bytes = self.take(len, what)?;
        let v: Vec<f64> = match dtype {
            DataType::F32 => bytes
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().unwrap()) as f64)
                .collect(),
            DataType::F64 => bytes
                .chunks_exact(8)
                .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
                .collect(),
        };
        if v.iter().any(|x| !x.is_finite()) {
            return Err(fmt_err(format!(
                "malformed table: {what} holds a non-finite value"
            )));
        }
        Ok(v)
    }
}

/// Check the header (magic, version, data type, length, SHA-256) and return
/// the data type, the format version and the payload.
fn check_header(b: &[u8]) -> Result<(DataType, u32, &[u8]), BrdfError> {
    if b.len() < MAGIC.len() || b[..MAGIC.len()] != MAGIC {
        return Err(fmt_err(format!(
            "not a polbrdf table: bad magic bytes (expected {:?})",
            std::str::from_utf8(&MAGIC).unwrap()
        )));
    }
    if b.len() < HEADER_LEN {
        return Err(fmt_err(format!(
            "truncated table: {} bytes, shorter than the {HEADER_LEN}-byte header",
            b.len()
        )));
    }
    let version = u32::from_le_bytes(b[8..12].try_into().unwrap());
    if !(OLDEST_READ_VERSION..=VERSION).contains(&version) {
        return Err(fmt_err(format!(
            "unsupported table format version {version} (this build reads versions {OLDEST_READ_VERSION} to {VERSION})"
        )));
    }
    let dtype = match u32::from_le_bytes(b[12..16].try_into().unwrap()) {
        1 => DataType::F32,
        2 => DataType::F64,
        c => return Err(fmt_err(format!("unknown data type code {c} in the header"))),
    };
    let announced = u64::from_le_bytes(b[16..24].try_into().unwrap());
    let have = (b.len() - HEADER_LEN) as u64;
    if have < announced {
        return Err(fmt_err(format!(
            "truncated table: the header announces {announced} bytes of content, the file has {have}"
        )));
    }
    if have > announced {
        return Err(fmt_err(format!(
            "malformed table: {} bytes after the announced end of the content",
            have - announced
        )));
    }
    let payload = &b[HEADER_LEN..];
    let sha = checksum(&b[..24], payload);
    if sha[..] != b[24..56] {
        return Err(fmt_err(format!(
            "checksum mismatch: the table is corrupted (SHA-256 in the header {}, of the content {})",
            hex(&b[24..56]),
            hex(&sha)
        )));
    }
    Ok((dtype, version, payload))
}

/// Parse a table file's bytes (docs/table-format.md), verifying the header
/// and the SHA-256 first.
pub fn from_bytes(b: &[u8]) -> Result<Table, BrdfError> {
    let (dtype, version, payload) = check_header(b)?;
    let mut c = Cursor { b: payload, at: 0 };
    let meta_len = c.u64("metadata length")?;
    let meta_len = usize::try_from(meta_len).map_err(|_| fmt_err("metadata too long"))?;
    let meta: Metadata = serde_json::from_slice(c.take(meta_len, "metadata")?)
        .map_err(|e| fmt_err(format!("malformed table metadata: {e}")))?;
    let w = c.u32("wavelength count")? as usize;
    let n = c.u32("node count")? as usize;
    let ns = c.u32("Stokes components")? as usize;
    let flags = c.u32("flags")?;
    if ns != 1 && ns != 4 {
        return Err(fmt_err(format!("malformed table: {ns} Stokes components")));
    }
    if flags > 31 || (flags & 16 == 16 && version < 6) {
        return Err(fmt_err(format!(
            "malformed table: unknown flags {flags:#x}"
        )));
    }
    if w == 0 || meta.wavelengths.len() != w {
        return Err(fmt_err(format!(
            "malformed table: {w} wavelength blocks, metadata lists {}",
            meta.wavelengths.len()
        )));
    }
    let theta = c.f64s(n, "polar nodes")?;
    let mu = c.f64s(n, "polar cosines")?;
    let grid = PolarGrid::from_theta_deg(theta)
        .map_err(|e| fmt_err(format!("malformed table: polar grid: {e}")))?;
    if grid.mu.iter().zip(&mu).any(|(a, b)| (a - b).abs() > 1e-12) {
        return Err(fmt_err(
            "malformed table: the stored cosines are not cos θ of the stored nodes",
        ));
    }
    let grid = PolarGrid { mu, ..grid };
    let wl = c.f64s(w, "wavelengths")?;
    let mut orders = Vec::with_capacity(w);
    for _ in 0..w {
        orders.push(c.u32("Fourier orders")? as usize);
    }
    let column_only = flags & 4 == 4;
    let (cols, sr, sc) = if column_only { (1, ns, 1) } else { (ns, 4, 4) };
    let incident = if flags & 8 == 8 {
        let k = c.u32("incident node count")? as usize;
        let mut v = Vec::with_capacity(k.min(n));
        for _ in 0..k {
            v.push(c.u32("incident nodes")? as usize);
        }
        if k == 0 || v.windows(2).any(|p| p[1] <= p[0]) || v[k - 1] >= n {
            return Err(fmt_err(
                "malformed table: the incident nodes are not increasing grid nodes",
            ));
        }
        v
    } else {
        (0..n).collect()
    };
    let expected = match (column_only, ns) {
        (false, _) => StokesNeed::Full,
        (true, 4) => StokesNeed::UnpolarizedIn,
        (true, _) => StokesNeed::Intensity,
    };
    if meta.stokes != expected {
        return Err(fmt_err(format!(
            "malformed table: the metadata says stokes {:?}, the layout holds {:?}",
            meta.stokes.name(),
            expected.name()
        )));
    }
    if (flags & 8 == 8) != meta.theta_i_deg.is_some() {
        return Err(fmt_err(
            "malformed table: incident nodes listed without needs.theta_i_deg in the metadata, or the reverse",
        ));
    }
    let kn = incident.len();
    let mut blocks = Vec::with_capacity(w);
    for k in 0..w {
        let count = orders[k]
            .checked_mul(n * kn * ns * cols)
            .ok_or_else(|| fmt_err("size overflow"))?;
        let f = c.data(count, dtype, "coefficients")?;
        let specular = if flags & 1 == 1 {
            let v = c.data(kn * sr * sc, dtype, "specular matrices")?;
            Some(
                v.chunks_exact(sr * sc)
                    .map(|ch| {
                        let mut m: Mueller = [[0.0; 4]; 4];
                        for (p, row) in m.iter_mut().enumerate().take(sr) {
                            row[..sc].copy_from_slice(&ch[sc * p..sc * p + sc]);
                        }
                        m
                    })
                    .collect(),
            )
        } else {
            None
        };
        let correction = if flags & 2 == 2 {
            get_correction(&mut c, version)?
        } else {
            None
        };
        let surface = if flags & 16 == 16 {
            get_surface(&mut c)?
        } else {
            None
        };
        blocks.push(WavelengthTable {
            wavelength_nm: if wl[k].is_nan() { None } else { Some(wl[k]) },
            ns,
            cols,
            nodes: n,
            incident: incident.clone(),
            orders: orders[k],
            f,
            specular,
            wall_time_ms: meta.wavelengths[k].wall_time_ms,
            correction,
            surface,
        });
    }
    if c.at != payload.len() {
        return Err(fmt_err(format!(
            "malformed table: {} unread bytes at the end of the content",
            payload.len() - c.at
        )));
    }
    Ok(Table {
        metadata: meta,
        grid,
        wavelengths: blocks,
    })
}

/// Write a table file (via a temporary file in the same directory, renamed
/// into place, so a reader never sees a half-written table).
pub fn write_file(table: &Table, path: &str, dtype: DataType) -> Result<(), BrdfError> {
    let bytes = to_bytes(table, dtype)?;
    let tmp = format!("{path}.tmp{}", std::process::id());
    let io = |source| BrdfError::Io {
        path: path.to_string(),
        source,
    };
    std::fs::write(&tmp, &bytes).map_err(io)?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        io(e)
    })
}

/// Read and verify a table file.
pub fn read_file(path: &str) -> Result<Table, BrdfError> {
    let b = std::fs::read(path).map_err(|source| BrdfError::Io {
        path: path.to_string(),
        source,
    })?;
    from_bytes(&b).map_err(|e| match e {
        BrdfError::Format(m) => BrdfError::Format(format!("{path}: {m}")),
        other => other,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::table::Table;

    /// A small, quick, wavelength-free table; with a mirror base the
    /// specular block is present.
    fn small_table(mirror: bool) -> Table {
        let base = if mirror {
            r#"{"fresnel": {"material": {"n": 1.5, "k": 0.01}}}"#
        } else {
            r#""black""#
        };
        let text = format!(
            r#"{{"layers": [{{"optical_thickness": 0.3,
                 "scatterer": {{"rayleigh": {{"albedo": 0.9}}}}}}],
                "base": {base}, "solver": {{"streams": 4}}}}"#
        );
        let spec = crate::material::parse(&text).unwrap();
        Table::from_spec(&spec, PolarGrid::graded(7).unwrap()).unwrap()
    }

    #[test]
    fn round_trip_f64_is_exact_and_f32_is_rounded() {
        for mirror in [false, true] {
            let t = small_table(mirror);
            assert_eq!(t.wavelengths[0].specular.is_some(), mirror);
            let back = from_bytes(&to_bytes(&t, DataType::F64).unwrap()).unwrap();
            assert_eq!(back, t);
            let back = from_bytes(&to_bytes(&t, DataType::F32).unwrap()).unwrap();
            assert_eq!(back.grid, t.grid);
            assert_eq!(back.metadata, t.metadata);
            for (a, b) in back.wavelengths[0].f.iter().zip(&t.wavelengths[0].f) {
                assert!((a - b).abs() <= 6e-8 * b.abs());
            }
        }
    }

    /// A truncated solve's correction record (layers, expansions, mirror
    /// indices) survives the round trip, and the rebuilt mirror closure
    /// evaluates to the same BRDF.
    #[test]
    fn correction_records_round_trip() {
        let text = r#"{"layers": [{"optical_thickness": 0.5, "scatterer": {"mie": {
             "material": {"n": 1.5, "k": 0.001}, "radius_um": 1.0, "host_index": 1.0}}}],
             "base": {"fresnel": {"material": {"n": 0.14, "k": 4.1}}},
             "wavelengths_nm": [550], "solver": {"streams": 4}}"#;
        let spec = crate::material::parse(text).unwrap();
        let t = Table::from_spec(&spec, PolarGrid::graded(6).unwrap()).unwrap();
        assert!(t.wavelengths[0].correction.is_some());
        let back = from_bytes(&to_bytes(&t, DataType::F32).unwrap()).unwrap();
        assert_eq!(back.wavelengths[0].correction, t.wavelengths[0].correction);
        let (a, b) = (&t.wavelengths[0], &back.wavelengths[0]);
        let (mut fa, mut fb) = ([[0.0; 4]; 4], [[0.0; 4]; 4]);
        a.complete(&mut fa, 80.0, 85.0, 0.3);
        b.complete(&mut fb, 80.0, 85.0, 0.3);
        assert_eq!(fa, fb);
        assert!(fa[0][0] != 0.0);
    }

    /// A truncated solve under a smooth top interface: the record keeps
    /// the binder index, and the correction read back is evaluated across
    /// the interface as the one written.
    #[test]
    fn interface_correction_records_round_trip() {
        let text = r#"{"layers": [{"optical_thickness": 0.5, "scatterer": {"mie": {
             "material": {"n": 2.0, "k": 0.001}, "radius_um": 1.0, "host_index": 1.5}}}],
             "top_interface": {"smooth": {}},
             "wavelengths_nm": [550], "solver": {"streams": 4}}"#;
        let spec = crate::material::parse(text).unwrap();
        let t = Table::from_spec(&spec, PolarGrid::graded(6).unwrap()).unwrap();
        let c = t.wavelengths[0].correction.as_ref().expect("truncated");
        assert_eq!(c.interface_index, Some(1.5));
        let back = from_bytes(&to_bytes(&t, DataType::F64).unwrap()).unwrap();
        assert_eq!(back, t);
        let (a, b) = (&t.wavelengths[0], &back.wavelengths[0]);
        let (mut fa, mut fb) = ([[0.0; 4]; 4], [[0.0; 4]; 4]);
        a.complete(&mut fa, 40.0, 35.0, 0.3);
        b.complete(&mut fb, 40.0, 35.0, 0.3);
        assert_eq!(fa, fb);
    }

    /// Tables without a top interface are written in version 4 (the
    /// correction record without the interface index, every earlier
    /// writer's bytes); a table whose correction carries an interface
    /// index is version 5 and is 8 bytes per record longer.
    #[test]
    fn the_oldest_version_that_holds_the_table_is_written() {
        let mie = |host: &str, interface: &str| {
            let text = format!(
                r#"{{"layers": [{{"optical_thickness": 0.5, "scatterer": {{"mie": {{
                 "material": {{"n": 2.0, "k": 0.001}}, "radius_um": 1.0,
                 "host_index": {host}}}}}}}], {interface}
                 "wavelengths_nm": [550], "solver": {{"streams": 4}}}}"#
            );
            let spec = crate::material::parse(&text).unwrap();
            Table::from_spec(&spec, PolarGrid::graded(6).unwrap()).unwrap()
        };
        let version = |b: &[u8]| u32::from_le_bytes(b[8..12].try_into().unwrap());
        let plain = to_bytes(&mie("1.5", ""), DataType::F64).unwrap();
        assert_eq!(version(&plain), 4);
        let under = mie("1.5", r#""top_interface": {"smooth": {}},"#);
        let bytes = to_bytes(&under, DataType::F64).unwrap();
        assert_eq!(version(&bytes), 5);
        assert_eq!(from_bytes(&bytes).unwrap(), under);
        // The same record layout but for the index (the metadata differ by
        // the spec's `top_interface`): a v5 record read as v4 is refused.
        let mut as_v4 = bytes.clone();
        as_v4[8..12].copy_from_slice(&4u32.to_le_bytes());
        let sha = checksum(&as_v4[..24], &as_v4[HEADER_LEN..]);
        as_v4[24..56].copy_from_slice(&sha);
        assert!(from_bytes(&as_v4).is_err());
    }

    /// A table under a rough top interface carries the surface's own
    /// reflection as a record (T4): version 6, read back equal, evaluated to
    /// the same BRDF (its gloss lobe, not in the coefficients); the same
    /// bytes labelled version 5 are refused.
    #[test]
    fn surface_records_round_trip_in_version_6() {
        let text = r#"{"layers": [{"optical_thickness": 0.5,
             "scatterer": {"rayleigh": {"albedo": 0.9}}}],
             "top_interface": {"rough": {"index": 1.5, "alpha": 0.3}},
             "solver": {"streams": 4}}"#;
        let spec = crate::material::parse(text).unwrap();
        let t = Table::from_spec(&spec, PolarGrid::graded(6).unwrap()).unwrap();
        let s = t.wavelengths[0].surface.expect("a rough interface");
        assert_eq!(
            (s.ambient, s.index.n, s.index.k, s.alpha),
            (1.0, 1.5, 0.0, 0.3)
        );
        let bytes = to_bytes(&t, DataType::F32).unwrap();
        assert_eq!(u32::from_le_bytes(bytes[8..12].try_into().unwrap()), 6);
        let back = from_bytes(&bytes).unwrap();
        assert_eq!(back.wavelengths[0].surface, Some(s));
        let (mut fa, mut fb) = ([[0.0; 4]; 4], [[0.0; 4]; 4]);
        t.wavelengths[0].complete(&mut fa, 40.0, 40.0, 0.0);
        back.wavelengths[0].complete(&mut fb, 40.0, 40.0, 0.0);
        assert_eq!(fa, fb);
        // At the mirror pair the lobe alone, D F G / (4 μ μ) with the GGX
        // D(h = n) = 1/(π α²) and F the unpolarized Fresnel reflectance.
        let mu: f64 = 40f64.to_radians().cos();
        let cos_t = (1.0 - (40f64.to_radians().sin() / 1.5).powi(2)).sqrt();
        let rs = (mu - 1.5 * cos_t) / (mu + 1.5 * cos_t);
        let rp = (1.5 * mu - cos_t) / (1.5 * mu + cos_t);
        let lambda = |m: f64| (-1.0 + (1.0 + 0.09 * (1.0 - m * m) / (m * m)).sqrt()) / 2.0;
        let g = 1.0 / (1.0 + 2.0 * lambda(mu));
        let d = 1.0 / (std::f64::consts::PI * 0.09);
        let want = d * g * 0.5 * (rs * rs + rp * rp) / (4.0 * mu * mu);
        assert!(
            (fa[0][0] - want).abs() < 1e-12 * want,
            "{} vs {want}",
            fa[0][0]
        );
        let mut as_v5 = bytes.clone();
        as_v5[8..12].copy_from_slice(&5u32.to_le_bytes());
        let sha = checksum(&as_v5[..24], &as_v5[HEADER_LEN..]);
        as_v5[24..56].copy_from_slice(&sha);
        assert!(
            message(&as_v5).contains("unknown flags"),
            "{}",
            message(&as_v5)
        );
    }

    #[test]
    fn header_layout_is_as_documented() {
        let b = to_bytes(&small_table(false), DataType::F32).unwrap();
        assert_eq!(&b[..8], b"PBRDFTAB");
        assert_eq!(u32::from_le_bytes(b[8..12].try_into().unwrap()), 4);
        assert_eq!((OLDEST_READ_VERSION, VERSION), (4, 6));
        assert_eq!(u32::from_le_bytes(b[12..16].try_into().unwrap()), 1);
        let len = u64::from_le_bytes(b[16..24].try_into().unwrap()) as usize;
        assert_eq!(len, b.len() - HEADER_LEN);
        // The checksum is the SHA-256 of bytes 0..24 and the payload,
        // computed here with the sha2 crate, independently of `checksum`.
        use sha2::Digest;
        let mut all = b[..24].to_vec();
        all.extend_from_slice(&b[HEADER_LEN..]);
        assert_eq!(sha2::Sha256::digest(&all)[..], b[24..56]);
    }

    fn message(b: &[u8]) -> String {
        match from_bytes(b) {
            Err(BrdfError::Format(m)) => m,
            other => panic!("expected a format error, got {other:?}"),
        }
    }

    #[test]
    fn every_flipped_byte_is_rejected() {
        let b = to_bytes(&small_table(true), DataType::F64).unwrap();
        // Every header byte and a spread of payload bytes.
        let positions: Vec<usize> = (0..HEADER_LEN)
            .chain((HEADER_LEN..b.len()).step_by(97))
            .chain([b.len() - 1])
            .collect();
        for &k in &positions {
            let mut c = b.clone();
            c[k] ^= 0x10;
            let m = message(&c);
            let expect = match k {
                0..8 => "bad magic",
                8..12 => "unsupported table format version",
                12..16 => "unknown data type",
                16..24 => "content",
                _ => "checksum mismatch",
            };
            assert!(
                m.contains(expect) || (k < 24 && m.contains("malformed")),
                "byte {k}: {m}"
            );
        }
    }

    #[test]
    fn truncation_and_wrong_magic_are_rejected() {
        let b = to_bytes(&small_table(false), DataType::F64).unwrap();
        for cut in [0, 5, 20, HEADER_LEN, HEADER_LEN + 10, b.len() - 1] {
            let m = message(&b[..cut]);
            assert!(
                m.contains("truncated") || (cut < 8 && m.contains("bad magic")),
                "cut at {cut}: {m}"
            );
        }
        let mut c = b.clone();
        c[..8].copy_from_slice(b"\x93NUMPY\x01\x00");
        assert!(message(&c).contains("not a polbrdf table"));
        let mut c = b.clone();
        c.push(0);
        assert!(message(&c).contains("after the announced end"));
    }
}
