//! Reflection and transmission operators of one Fourier order: a thin-layer
//! start, doubling, and the adding equations (van de Hulst 1980; Hansen &
//! Travis 1974 §3; de Haan, Bosma & Hovenier 1987; the structure follows
//! `wjakob/layerlab`: one struct per order with the R/T blocks, `add` never
//! forms an inverse but factorises once and solves).
//!
//! ## Directions and blocks
//! *Quadrature* directions carry weights and take part in scattering: `N`
//! double-Gauss cosines per hemisphere, `n = N·ns` unknowns per hemisphere
//! (`ns` = 4 Stokes components, or 1 in the scalar case).
//! *User* directions (`U` cosines, `nu = U·ns`) have zero weight: radiance in
//! them is an output (exact source-function integration, carried as
//! rectangular blocks) and collimated **beams** arrive along them.
//!
//! Operators act on vectors of radiance Fourier components (conventions §5,
//! S1 set of `solver::phase`). Names: `r`/`t` act on light entering at the top
//! (travelling down), `rs`/`ts` ("star") on light entering at the bottom
//! (travelling up); `r*` outputs leave through the entry face, `t*` through
//! the other face. Suffix `u` = rows are user directions; `b` = columns are
//! beams; `uu` = both. The quadrature `t`, `ts` include the direct
//! transmission `e^{−τ/μ}` on their diagonal; beam and user-radiance direct
//! transmission is the diagonal `eu`.
//!
//! Files: the operators, the adding equations, the mirror base and the
//! doubling (here); the thin start layer, its kernel and the Richardson
//! extrapolation (`start`); the diffusion-regime continuation of
//! conservative layers (`diffusion`).

use faer::linalg::matmul::matmul;
use faer::prelude::*;
use faer::{Accum, Mat, MatRef};

mod diffusion;
mod start;

pub use diffusion::{DiffusionWatch, extrapolation_length};
pub use start::{
    Kernel, exp_divided_difference, linear_source_weights, richardson, richardson_top, thin_layer,
};

/// `dst (+)= a · b`, sequential (the solver parallelises over Fourier orders).
fn mm_into(dst: &mut Mat<f64>, accum: Accum, a: MatRef<'_, f64>, b: MatRef<'_, f64>) {
    matmul(dst.as_mut(), accum, a, b, 1.0, Par::Seq);
}

/// `a · b`.
pub fn mm(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let mut out = Mat::zeros(a.nrows(), b.ncols());
    if a.ncols() > 0 {
        mm_into(&mut out, Accum::Replace, a, b);
    }
    out
}

/// Operators of a slab (or a base) for one Fourier order.
#[derive(Clone, Debug)]
pub struct Ops {
    /// Quadrature block size `n`.
    pub n: usize,
    /// User/beam block size `nu`.
    pub nu: usize,
    /// Stokes components per direction.
    pub ns: usize,
    pub r: Mat<f64>,
    pub t: Mat<f64>,
    pub rs: Mat<f64>,
    pub ts: Mat<f64>,
    pub ru: Mat<f64>,
    pub tu: Mat<f64>,
    pub rus: Mat<f64>,
    pub tus: Mat<f64>,
    pub rb: Mat<f64>,
    pub tb: Mat<f64>,
    pub rbs: Mat<f64>,
    pub tbs: Mat<f64>,
    pub ruu: Mat<f64>,
    pub tuu: Mat<f64>,
    pub ruus: Mat<f64>,
    pub tuus: Mat<f64>,
    /// Direct transmission `e^{−τ/μ_u}` of each user direction (length `nu/ns`).
    pub eu: Vec<f64>,
}

impl Ops {
    /// The operators of an empty slab (`τ = 0`): identity transmission.
    pub fn vacuum(n: usize, nu: usize, ns: usize) -> Self {
        let z = |a, b| Mat::<f64>::zeros(a, b);
        Self {
            n,
            nu,
            ns,
            r: z(n, n),
            t: Mat::identity(n, n),
            rs: z(n, n),
            ts: Mat::identity(n, n),
            ru: z(nu, n),
            tu: z(nu, n),
            rus: z(nu, n),
            tus: z(nu, n),
            rb: z(n, nu),
            tb: z(n, nu),
            rbs: z(n, nu),
            tbs: z(n, nu),
            ruu: z(nu, nu),
            tuu: z(nu, nu),
            ruus: z(nu, nu),
            tuus: z(nu, nu),
            eu: vec![1.0; nu / ns.max(1)],
        }
    }

    /// A slab of optical thickness `tau` that does not scatter (in this
    /// Fourier order): direct transmission `e^{−τ/μ}` only, along the
    /// quadrature cosines `mu_q` and the user cosines `mu_u`.
    pub fn attenuator(tau: f64, mu_q: &[f64], mu_u: &[f64], ns: usize) -> Self {
        let mut o = Self::vacuum(mu_q.len() * ns, mu_u.len() * ns, ns);
        for (i, &mu) in mu_q.iter().enumerate() {
            let e = (-tau / mu).exp();
            for p in 0..ns {
                o.t[(i * ns + p, i * ns + p)] = e;
                o.ts[(i * ns + p, i * ns + p)] = e;
            }
        }
        o.eu = mu_u.iter().map(|&mu| (-tau / mu).exp()).collect();
        o
    }

    /// A reflector with no transmission (a base): all `t` blocks zero.
    pub fn reflector(n: usize, nu: usize, ns: usize) -> Self {
        let mut o = Self::vacuum(n, nu, ns);
        o.t = Mat::zeros(n, n);
        o.ts = Mat::zeros(n, n);
        o.eu = vec![0.0; nu / ns.max(1)];
        o
    }

    /// Assemble from the four output row blocks, each with input columns
    /// `[x | b | y | c]` (see `Cols`): quadrature light leaving the top,
    /// quadrature light leaving the bottom, user radiance leaving the top,
    /// user radiance leaving the bottom.
    fn from_column_blocks(cols: &Cols, ns: usize, rows: [&Mat<f64>; 4], eu: Vec<f64>) -> Self {
        let [r, rb, ts, tbs] = cols.split(rows[0]);
        let [t, tb, rs, rbs] = cols.split(rows[1]);
        let [ru, ruu, tus, tuus] = cols.split(rows[2]);
        let [tu, tuu, rus, ruus] = cols.split(rows[3]);
        Self {
            n: cols.n,
            nu: ru.nrows(),
            ns,
            r,
            t,
            rs,
            ts,
            ru,
            tu,
            rus,
            tus,
            rb,
            tb,
            rbs,
            tbs,
            ruu,
            tuu,
            ruus,
            tuus,
            eu,
        }
    }

    /// Largest absolute entry of the quadrature transmission (used to stop
    /// doubling a semi-infinite layer).
    pub fn max_abs_t(&self) -> f64 {
        max_abs(self.t.as_ref()).max(max_abs(self.ts.as_ref()))
    }
}

/// `I − A B` (the matrix of the adding equations' multiple reflections).
pub fn identity_minus_product(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let mut g = Mat::<f64>::identity(a.nrows(), b.ncols());
    matmul(g.as_mut(), Accum::Add, a, b, -1.0, Par::Seq);
    g
}

/// Solve `G X = B` with one step of iterative refinement (Wilkinson 1963):
/// `X ← X + G⁻¹(B − G X)`. In thick conservative layers `G = I − R* R` is
/// nearly singular (its condition grows like τ); refinement keeps the
/// doubling's flux balance at round-off level.
pub fn refined_solve(
    g: &Mat<f64>,
    lu: &faer::linalg::solvers::PartialPivLu<f64>,
    b: &Mat<f64>,
) -> Mat<f64> {
    let mut x = lu.solve(b);
    let mut r = b.clone();
    matmul(
        r.as_mut(),
        Accum::Add,
        g.as_ref(),
        x.as_ref(),
        -1.0,
        Par::Seq,
    );
    let dx = lu.solve(&r);
    x += &dx;
    x
}

/// Largest absolute entry of a matrix; NaN if any entry is NaN (so that
/// callers checking `is_finite` see it: `f64::max` would drop a NaN).
pub fn max_abs(m: MatRef<'_, f64>) -> f64 {
    let mut v: f64 = 0.0;
    for j in 0..m.ncols() {
        for i in 0..m.nrows() {
            let x = m[(i, j)];
            if x.is_nan() {
                return f64::NAN;
            }
            v = v.max(x.abs());
        }
    }
    v
}

/// Multiply the columns of `m` belonging to user/beam direction `v` (blocks of
/// `ns` columns) by `e[v]`.
fn scale_cols(m: &Mat<f64>, e: &[f64], ns: usize) -> Mat<f64> {
    let mut o = m.clone();
    for (v, &ev) in e.iter().enumerate() {
        for s in 0..ns {
            let j = v * ns + s;
            for i in 0..o.nrows() {
                o[(i, j)] *= ev;
            }
        }
    }
    o
}

/// Multiply the rows of `m` belonging to user direction `u` by `e[u]`.
fn scale_rows(m: &Mat<f64>, e: &[f64], ns: usize) -> Mat<f64> {
    let mut o = m.clone();
    for (u, &eu) in e.iter().enumerate() {
        for s in 0..ns {
            let i = u * ns + s;
            for j in 0..o.ncols() {
                o[(i, j)] *= eu;
            }
        }
    }
    o
}

/// Column blocks `[x | b | y | c]` for the four kinds of input: quadrature
/// light entering at the top (`x`, width n), a beam entering at the top (`b`,
/// nu), quadrature light entering at the bottom (`y`, n), a beam entering at
/// the bottom (`c`, nu).
struct Cols {
    n: usize,
    nu: usize,
}

impl Cols {
    fn width(&self) -> usize {
        2 * self.n + 2 * self.nu
    }
    fn offsets(&self) -> [usize; 4] {
        [0, self.n, self.n + self.nu, 2 * self.n + self.nu]
    }
    fn widths(&self) -> [usize; 4] {
        [self.n, self.nu, self.n, self.nu]
    }
    /// Assemble `[x | b | y | c]` from optional blocks (None = zero).
    fn assemble(&self, rows: usize, blocks: [Option<&Mat<f64>>; 4]) -> Mat<f64> {
        let mut out = Mat::zeros(rows, self.width());
        let off = self.offsets();
        let wid = self.widths();
        for k in 0..4 {
            if let Some(b) = blocks[k] {
                debug_assert_eq!(b.nrows(), rows);
                debug_assert_eq!(b.ncols(), wid[k]);
                out.as_mut()
                    .submatrix_mut(0, off[k], rows, wid[k])
                    .copy_from(b.as_ref());
            }
        }
        out
    }
    fn split(&self, m: &Mat<f64>) -> [Mat<f64>; 4] {
        let off = self.offsets();
        let wid = self.widths();
        std::array::from_fn(|k| {
            m.as_ref()
                .submatrix(0, off[k], m.nrows(), wid[k])
                .to_owned()
        })
    }
}

/// The adding equations: slab `a` on top of slab `b` (van de Hulst 1980,
/// ch. 4; Hansen & Travis 1974 eq. 30–33), extended to user rows and beam
/// columns.
///
/// With `G = (I − R*_a R_b)^{-1}` (factorised, never inverted) the quadrature
/// radiance at the interface is, for inputs `[x | b | y | c]`,
/// `D = G (X + R*_a V)` travelling down and `U = R_b D + V` travelling up,
/// where `X = [T_a | Tb_a | 0 | Rb*_a E_b]` and `V = [0 | Rb_b E_a | T*_b | Tb*_b]`.
/// Outputs then follow by one product each; user radiance that reaches the
/// interface crosses the other slab with its direct transmission only (zero
/// weight: it does not scatter).
///
/// With `full = false` only what the response at the top needs is computed
/// (quadrature outputs for top inputs and bottom quadrature input, user rows
/// leaving the top); the blocks for a beam entering at the bottom and the
/// user rows leaving the bottom are left zero.
pub fn add(a: &Ops, b: &Ops, full: bool) -> Ops {
    let (n, nu, ns) = (a.n, a.nu, a.ns);
    let cols = Cols { n, nu };
    let rbb_ea = scale_cols(&b.rb, &a.eu, ns);
    let rbsa_eb = scale_cols(&a.rbs, &b.eu, ns);
    let v = cols.assemble(n, [None, Some(&rbb_ea), Some(&b.ts), Some(&b.tbs)]);
    let x = cols.assemble(n, [Some(&a.t), Some(&a.tb), None, Some(&rbsa_eb)]);

    // G = (I − R*_a R_b)^{-1}: factorise once, solve.
    let g = identity_minus_product(a.rs.as_ref(), b.r.as_ref());
    let lu = g.partial_piv_lu();
    let mut rhs = x;
    mm_into(&mut rhs, Accum::Add, a.rs.as_ref(), v.as_ref());
    let d = refined_solve(&g, &lu, &rhs);
    let mut u = v;
    mm_into(&mut u, Accum::Add, b.r.as_ref(), d.as_ref());

    // Quadrature light leaving the top.
    let tbsa_eb = scale_cols(&a.tbs, &b.eu, ns);
    let mut top_q = cols.assemble(n, [Some(&a.r), Some(&a.rb), None, Some(&tbsa_eb)]);
    mm_into(&mut top_q, Accum::Add, a.ts.as_ref(), u.as_ref());
    // Quadrature light leaving the bottom.
    let tbb_ea = scale_cols(&b.tb, &a.eu, ns);
    let mut bot_q = cols.assemble(n, [None, Some(&tbb_ea), Some(&b.rs), Some(&b.rbs)]);
    mm_into(&mut bot_q, Accum::Add, b.t.as_ref(), d.as_ref());

    // User radiance leaving the top: from a directly, and from b's top
    // crossing a with its direct transmission.
    let tuusa_eb = scale_cols(&a.tuus, &b.eu, ns);
    let mut top_u = cols.assemble(nu, [Some(&a.ru), Some(&a.ruu), None, Some(&tuusa_eb)]);
    mm_into(&mut top_u, Accum::Add, a.tus.as_ref(), u.as_ref());
    let ruub_ea = scale_cols(&b.ruu, &a.eu, ns);
    let mut from_b = cols.assemble(nu, [None, Some(&ruub_ea), Some(&b.tus), Some(&b.tuus)]);
    mm_into(&mut from_b, Accum::Add, b.ru.as_ref(), d.as_ref());
    let from_b = scale_rows(&from_b, &a.eu, ns);
    top_u += &from_b;

    // User radiance leaving the bottom.
    if !full {
        let [r, rb, ts, _] = cols.split(&top_q);
        let [t, tb, rs, _] = cols.split(&bot_q);
        let [ru, ruu, tus, _] = cols.split(&top_u);
        let z = |a, b| Mat::<f64>::zeros(a, b);
        return Ops {
            n,
            nu,
            ns,
            r,
            t,
            rs,
            ts,
            ru,
            tu: z(nu, n),
            rus: z(nu, n),
            tus,
            rb,
            tb,
            rbs: z(n, nu),
            tbs: z(n, nu),
            ruu,
            tuu: z(nu, nu),
            ruus: z(nu, nu),
            tuus: z(nu, nu),
            eu: a.eu.iter().zip(&b.eu).map(|(x, y)| x * y).collect(),
        };
    }
    let tuub_ea = scale_cols(&b.tuu, &a.eu, ns);
    let mut bot_u = cols.assemble(nu, [None, Some(&tuub_ea), Some(&b.rus), Some(&b.ruus)]);
    mm_into(&mut bot_u, Accum::Add, b.tu.as_ref(), d.as_ref());
    let ruusa_eb = scale_cols(&a.ruus, &b.eu, ns);
    let mut from_a = cols.assemble(nu, [Some(&a.tu), Some(&a.tuu), None, Some(&ruusa_eb)]);
    mm_into(&mut from_a, Accum::Add, a.rus.as_ref(), u.as_ref());
    let from_a = scale_rows(&from_a, &b.eu, ns);
    bot_u += &from_a;

    let eu = a.eu.iter().zip(&b.eu).map(|(x, y)| x * y).collect();
    Ops::from_column_blocks(&cols, ns, [&top_q, &bot_q, &top_u, &bot_u], eu)
}

/// Result of putting a stack on a specular (mirror) base: the operators seen
/// from the top, for inputs `[x | b]`.
#[derive(Clone, Debug)]
pub struct TopResponse {
    /// Quadrature radiance leaving the top from quadrature input.
    pub r: Mat<f64>,
    /// Quadrature radiance leaving the top from a beam.
    pub rb: Mat<f64>,
    /// User radiance leaving the top from quadrature input.
    pub ru: Mat<f64>,
    /// User radiance leaving the top from a beam (the BRDF core).
    pub ruu: Mat<f64>,
}

impl TopResponse {
    /// The blocks of a slab's (or a stack's) operators seen from the top.
    pub fn of(o: Ops) -> Self {
        Self {
            r: o.r,
            rb: o.rb,
            ru: o.ru,
            ruu: o.ruu,
        }
    }
}

/// Stack `a` on a specular base that maps downward radiance in direction
/// `μ` to upward radiance in the same `μ` with a 4×4 matrix (the Fresnel
/// Mueller matrix): `mq` is that map on the quadrature directions (n×n,
/// block diagonal), `mu_blocks` on the user directions (nu×nu, block
/// diagonal). A beam reaching the mirror is reflected as a beam, which then
/// scatters in `a` from below; zero-weight user radiance reaching the mirror
/// is reflected and crosses `a` directly. The doubly attenuated specular beam
/// itself is not included (it is a delta, reported separately).
pub fn add_mirror(a: &Ops, mq: &Mat<f64>, mu_blocks: &Mat<f64>) -> TopResponse {
    let (n, nu, ns) = (a.n, a.nu, a.ns);
    // Beam-up at the interface per unit beam-down at the top: C = M_u E_a.
    let c = scale_cols(mu_blocks, &a.eu, ns);
    // `[x_block | b_block + beam_up · C]` for inputs `[x | b]`.
    let with_beam_up = |x_block: &Mat<f64>, b_block: &Mat<f64>, beam_up: &Mat<f64>| -> Mat<f64> {
        let rows = x_block.nrows();
        let mut out = Mat::zeros(rows, n + nu);
        out.as_mut()
            .submatrix_mut(0, 0, rows, n)
            .copy_from(x_block.as_ref());
        let mut b = b_block.clone();
        mm_into(&mut b, Accum::Add, beam_up.as_ref(), c.as_ref());
        out.as_mut()
            .submatrix_mut(0, n, rows, nu)
            .copy_from(b.as_ref());
        out
    };
    // D = G [T_a | Tb_a + Rb*_a C], G = (I − R*_a M_q)^{-1}; U = M_q D.
    let g = identity_minus_product(a.rs.as_ref(), mq.as_ref());
    let rhs = with_beam_up(&a.t, &a.tb, &a.rbs);
    let d = g.partial_piv_lu().solve(&rhs);
    let u = mm(mq.as_ref(), d.as_ref());

    let mut top_q = with_beam_up(&a.r, &a.rb, &a.tbs);
    mm_into(&mut top_q, Accum::Add, a.ts.as_ref(), u.as_ref());

    // User radiance going down at the interface, reflected by the mirror and
    // crossing `a` directly.
    let mut down_u = with_beam_up(&a.tu, &a.tuu, &a.ruus);
    mm_into(&mut down_u, Accum::Add, a.rus.as_ref(), u.as_ref());
    let up_u = scale_rows(&mm(mu_blocks.as_ref(), down_u.as_ref()), &a.eu, ns);

    let mut top_u = with_beam_up(&a.ru, &a.ruu, &a.tuus);
    mm_into(&mut top_u, Accum::Add, a.tus.as_ref(), u.as_ref());
    top_u += &up_u;

    TopResponse {
        r: top_q.as_ref().submatrix(0, 0, n, n).to_owned(),
        rb: top_q.as_ref().submatrix(0, n, n, nu).to_owned(),
        ru: top_u.as_ref().submatrix(0, 0, nu, n).to_owned(),
        ruu: top_u.as_ref().submatrix(0, n, nu, nu).to_owned(),
    }
}

/// The mirror symmetry of a homogeneous layer: `R* = S R S`, `T* = S T S`
/// with `S = diag(1, 1, −1, −1)` per direction (reflection in the horizontal
/// plane turns right-handed meridian frames into left-handed ones, flipping
/// U and V; test `symmetry_tests::mirror_symmetry_and_reciprocity`).
pub fn mirror(m: &Mat<f64>, ns: usize) -> Mat<f64> {
    let mut o = m.clone();
    if ns == 1 {
        return o;
    }
    let sgn = |i: usize| if i % ns < 2 { 1.0 } else { -1.0 };
    for j in 0..o.ncols() {
        for i in 0..o.nrows() {
            o[(i, j)] *= sgn(i) * sgn(j);
        }
    }
    o
}

/// What the doubling of a homogeneous layer must carry for the response at
/// the top: `R`, `T` (the star operators follow by [`mirror`]), the user rows
/// `Ru` (user up at the top from quadrature light entering at the top) and
/// `Tu*` (user up at the top from quadrature light entering at the bottom),
/// and the direct transmission of user directions.
#[derive(Clone, Debug)]
pub struct TopOps {
    pub r: Mat<f64>,
    pub t: Mat<f64>,
    pub ru: Mat<f64>,
    pub tus: Mat<f64>,
    pub eu: Vec<f64>,
}

impl TopOps {
    /// Take the blocks from full operators.
    pub fn from_ops(o: &Ops) -> Self {
        Self {
            r: o.r.clone(),
            t: o.t.clone(),
            ru: o.ru.clone(),
            tus: o.tus.clone(),
            eu: o.eu.clone(),
        }
    }
}

/// One doubling step `τ → 2τ` of a homogeneous layer (adding equations of
/// [`add`] with `a = b` and the mirror symmetry): with `G = I − R* R`,
/// `D_x = G⁻¹T`, `U_x = R D_x`, `D_y = G⁻¹R* T*`, `U_y = R D_y + T*`:
/// `R' = R + T* U_x`, `T' = T D_x`, `Ru' = Ru + Tu* U_x + E Ru D_x`,
/// `Tu*' = Tu* U_y + E (Ru D_y + Tu*)`.
pub fn double_top(o: &TopOps, ns: usize) -> TopOps {
    let rs = mirror(&o.r, ns);
    let ts = mirror(&o.t, ns);
    let g = identity_minus_product(rs.as_ref(), o.r.as_ref());
    let lu = g.partial_piv_lu();
    let dx = refined_solve(&g, &lu, &o.t);
    let ux = mm(o.r.as_ref(), dx.as_ref());
    let dy = refined_solve(&g, &lu, &mm(rs.as_ref(), ts.as_ref()));
    let mut uy = ts.clone();
    mm_into(&mut uy, Accum::Add, o.r.as_ref(), dy.as_ref());
    let mut r = o.r.clone();
    mm_into(&mut r, Accum::Add, ts.as_ref(), ux.as_ref());
    let t = mm(o.t.as_ref(), dx.as_ref());
    // User rows: E·(Ru D_x) and E·(Ru D_y + Tu*) come from the lower copy.
    let mut lower_x = mm(o.ru.as_ref(), dx.as_ref());
    let mut lower_y = o.tus.clone();
    mm_into(&mut lower_y, Accum::Add, o.ru.as_ref(), dy.as_ref());
    lower_x = scale_rows(&lower_x, &o.eu, ns);
    lower_y = scale_rows(&lower_y, &o.eu, ns);
    let mut ru = o.ru.clone();
    mm_into(&mut ru, Accum::Add, o.tus.as_ref(), ux.as_ref());
    ru += &lower_x;
    let mut tus = lower_y;
    mm_into(&mut tus, Accum::Add, o.tus.as_ref(), uy.as_ref());
    TopOps {
        r,
        t,
        ru,
        tus,
        eu: o.eu.iter().map(|e| e * e).collect(),
    }
}

/// Complete top-only operators of a homogeneous layer of thickness `tau`
/// from the doubled [`TopOps`]:
///
/// * `R*`, `T*` by the mirror symmetry;
/// * beam columns by polarized reciprocity (Hovenier 1969; for the Fourier
///   components of the S1 set: `Rb[i,v] = (μ_v/(μ_i w_i)) Δ Ru[v,i]ᵀ Δ`,
///   `Tb[i,v] = (μ_v/(μ_i w_i)) Δ Tu*[v,i]ᵀ Δ` with `Δ = diag(1, 1, −1, 1)`;
///   test `symmetry_tests::mirror_symmetry_and_reciprocity`);
/// * the user-by-beam reflection `Ruu` from Chandrasekhar's principles of
///   invariance (Chandrasekhar 1950, §§50–51: adding a thin layer at the top
///   and at the bottom must give the same derivative), which is algebraic:
///   `(λ_u + λ_v) Ruu = ρ_ub (1 − E_u E_v) + Ru (ρ*_b + ρ* Rb) + ρ_u⁺ Rb
///   − (Tu* ρ + E_u ρ_u) Tb − Tu* ρ_b E_b` with `λ = 1/μ` and the `ρ` the
///   single-scattering rates of the kernel (per unit optical depth). It is
///   exact for the discrete-ordinate layer and costs one pass, instead of
///   carrying the `nu × nu` blocks through every doubling.
pub fn finish_top(
    o: &TopOps,
    k: &Kernel,
    mu_q: &[f64],
    w_q: &[f64],
    mu_u: &[f64],
    ns: usize,
    tau: f64,
) -> Ops {
    const UP: usize = 0;
    const DN: usize = 1;
    let n = o.r.nrows();
    let nu = o.ru.nrows();
    let dsign = |p: usize| if ns == 4 && p == 2 { -1.0 } else { 1.0 };
    let mut rb = Mat::<f64>::zeros(n, nu);
    let mut tb = Mat::<f64>::zeros(n, nu);
    for i in 0..mu_q.len() {
        for v in 0..mu_u.len() {
            let f = mu_u[v] / (mu_q[i] * w_q[i]);
            for p in 0..ns {
                for q in 0..ns {
                    let s = f * dsign(p) * dsign(q);
                    rb[(i * ns + p, v * ns + q)] = s * o.ru[(v * ns + q, i * ns + p)];
                    tb[(i * ns + p, v * ns + q)] = s * o.tus[(v * ns + q, i * ns + p)];
                }
            }
        }
    }
    // Single-scattering rates per unit depth.
    let inv_mu_q = |m: &Mat<f64>| {
        let mut o = m.clone();
        for i in 0..o.nrows() {
            let f = 1.0 / mu_q[i / ns];
            for j in 0..o.ncols() {
                o[(i, j)] *= f;
            }
        }
        o
    };
    let inv_mu_u = |m: &Mat<f64>| {
        let mut o = m.clone();
        for i in 0..o.nrows() {
            let f = 1.0 / mu_u[i / ns];
            for j in 0..o.ncols() {
                o[(i, j)] *= f;
            }
        }
        o
    };
    let rho_sb = inv_mu_q(&k.qb[DN][DN]); // quad down <- beam down
    let rho_s = inv_mu_q(&k.qq[DN][UP]); // quad down <- quad up
    let rho = inv_mu_q(&k.qq[UP][DN]); // quad up <- quad down
    let rho_b = inv_mu_q(&k.qb[UP][DN]); // quad up <- beam down
    let rho_up = inv_mu_u(&k.uq[UP][UP]); // user up <- quad up
    let rho_u = inv_mu_u(&k.uq[UP][DN]); // user up <- quad down
    let rho_ub = inv_mu_u(&k.ub[UP][DN]); // user up <- beam down

    // Ru (ρ*_b + ρ* Rb)
    let mut inner = rho_sb;
    mm_into(&mut inner, Accum::Add, rho_s.as_ref(), rb.as_ref());
    let mut acc = mm(o.ru.as_ref(), inner.as_ref());
    // + ρ_u⁺ Rb
    mm_into(&mut acc, Accum::Add, rho_up.as_ref(), rb.as_ref());
    // − (Tu* ρ + E_u ρ_u) Tb
    let mut left = scale_rows(&rho_u, &o.eu, ns);
    mm_into(&mut left, Accum::Add, o.tus.as_ref(), rho.as_ref());
    let lt = mm(left.as_ref(), tb.as_ref());
    acc -= &lt;
    // − Tu* ρ_b E_b
    let tb_dir = mm(o.tus.as_ref(), scale_cols(&rho_b, &o.eu, ns).as_ref());
    acc -= &tb_dir;
    let lam: Vec<f64> = mu_u.iter().map(|m| 1.0 / m).collect();
    let nd = mu_u.len();
    let mut ruu = Mat::<f64>::zeros(nu, nu);
    let mut single = vec![0.0; nd];
    let mut inv_s = vec![0.0; nd];
    for v in 0..nd {
        let lv = lam[v];
        for (u, &lu) in lam.iter().enumerate() {
            let s = lu + lv;
            inv_s[u] = 1.0 / s;
            single[u] = if tau.is_finite() {
                -(-tau * s).exp_m1()
            } else {
                1.0
            };
        }
        for q in 0..ns {
            let j = v * ns + q;
            for i in 0..nu {
                let u = i / ns;
                ruu[(i, j)] = (rho_ub[(i, j)] * single[u] + acc[(i, j)]) * inv_s[u];
            }
        }
    }
    let z = |a, b| Mat::<f64>::zeros(a, b);
    Ops {
        n,
        nu,
        ns,
        rs: mirror(&o.r, ns),
        ts: mirror(&o.t, ns),
        r: o.r.clone(),
        t: o.t.clone(),
        ru: o.ru.clone(),
        tu: z(nu, n),
        rus: z(nu, n),
        tus: o.tus.clone(),
        rb,
        tb,
        rbs: z(n, nu),
        tbs: z(n, nu),
        ruu,
        tuu: z(nu, nu),
        ruus: z(nu, nu),
        tuus: z(nu, nu),
        eu: o.eu.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::orders::{Grid, layer_ops};
    use crate::solver::{Layer, Settings, Thickness};

    /// A polarized Garcia–Siewert layer (order `m`, 6 streams, three user
    /// cosines), the discretisation and settings it was built with.
    fn slab(tau: f64, albedo: f64, m: usize) -> (Ops, Grid, Settings) {
        let settings = Settings {
            streams: 6,
            ..Settings::default()
        };
        let grid = Grid::new(&settings, &[0.15, 0.55, 0.95]);
        let layer = Layer {
            thickness: Thickness::Finite(tau),
            albedo,
            coef: crate::physics::expansion::test_data::garcia_siewert().truncated(11),
        };
        (layer_ops(&grid, &layer, m, &settings, true), grid, settings)
    }

    /// `(max |a − b|, max |b|)` over every block of two operators.
    fn ops_diff(a: &Ops, b: &Ops) -> (f64, f64) {
        let blocks = |o: &Ops| {
            [
                o.r.clone(),
                o.t.clone(),
                o.rs.clone(),
                o.ts.clone(),
                o.ru.clone(),
                o.tu.clone(),
                o.rus.clone(),
                o.tus.clone(),
                o.rb.clone(),
                o.tb.clone(),
                o.rbs.clone(),
                o.tbs.clone(),
                o.ruu.clone(),
                o.tuu.clone(),
                o.ruus.clone(),
                o.tuus.clone(),
            ]
        };
        let (mut d, mut scale): (f64, f64) = (0.0, 0.0);
        for (x, y) in blocks(a).iter().zip(&blocks(b)) {
            d = d.max(max_abs((x - y).as_ref()));
            scale = scale.max(max_abs(y.as_ref()));
        }
        for (x, y) in a.eu.iter().zip(&b.eu) {
            d = d.max((x - y).abs());
        }
        (d, scale)
    }

    /// Adding an empty slab above or below changes nothing.
    #[test]
    fn adding_a_layer_of_zero_thickness_is_the_identity() {
        for m in [0, 2] {
            let (a, g, _) = slab(0.7, 0.95, m);
            let vacuum = Ops::vacuum(a.n, a.nu, g.ns);
            for (name, sum) in [
                ("above", add(&vacuum, &a, true)),
                ("below", add(&a, &vacuum, true)),
            ] {
                let (d, scale) = ops_diff(&sum, &a);
                assert!(
                    d <= 1e-14 * scale,
                    "m = {m}, vacuum {name}: {d:e} of {scale:e}"
                );
            }
        }
    }

    /// `(A + B) + C = A + (B + C)` for three different slabs.
    #[test]
    fn adding_is_associative() {
        for m in [0, 1, 3] {
            let (a, _, _) = slab(0.3, 0.9, m);
            let (b, _, _) = slab(1.1, 0.99, m);
            let (c, _, _) = slab(0.05, 0.5, m);
            let left = add(&add(&a, &b, true), &c, true);
            let right = add(&a, &add(&b, &c, true), true);
            let (d, scale) = ops_diff(&left, &right);
            assert!(d <= 1e-13 * scale, "m = {m}: {d:e} of {scale:e}");
        }
    }

    /// One doubling step of the top-only path equals adding the layer to
    /// itself, and a layer of `2τ` built by `layer_ops` equals two of `τ`
    /// added (to its start layer's extrapolated discretisation error).
    #[test]
    fn doubling_is_adding_the_same_layer_twice() {
        for m in [0, 2] {
            let (a, g, settings) = slab(0.4, 0.97, m);
            let added = add(&a, &a, true);
            let doubled = double_top(&TopOps::from_ops(&a), g.ns);
            for (name, x, y) in [
                ("R", &doubled.r, &added.r),
                ("T", &doubled.t, &added.t),
                ("Ru", &doubled.ru, &added.ru),
                ("Tu*", &doubled.tus, &added.tus),
            ] {
                let d = max_abs((x - y).as_ref());
                let scale = max_abs(y.as_ref());
                // The same equations in another order: round-off through
                // the factorisation of I − R*R (1.0e-13 of max Tu* at m = 0
                // seen); a wrong term is O(1e-3) or more.
                assert!(
                    d <= 1e-12 * scale.max(1e-300),
                    "m = {m}, {name}: {d:e} of {scale:e}"
                );
            }
            assert_eq!(doubled.eu, added.eu);
            let layer = Layer {
                thickness: Thickness::Finite(0.8),
                albedo: 0.97,
                coef: crate::physics::expansion::test_data::garcia_siewert().truncated(11),
            };
            let thick = layer_ops(&g, &layer, m, &settings, true);
            let (d, scale) = ops_diff(&thick, &added);
            assert!(d <= 1e-9 * scale, "m = {m}, 2 tau: {d:e} of {scale:e}");
        }
    }

    /// Adding a slab over a mirror base (`add_mirror`) equals, on the
    /// quadrature streams, the generic adding equations with a reflector
    /// whose reflection is the mirror (`R = R_a + T*_a M (I − R*_a M)⁻¹ T_a`;
    /// the user rows differ by design: `add_mirror` also reflects the
    /// zero-weight user radiance, which a reflector's blocks cannot carry),
    /// and over an empty slab it is the mirror itself with no diffuse light.
    #[test]
    fn the_mirror_equals_its_closed_form() {
        let fresnel = |mu: f64| {
            crate::physics::fresnel::mueller(
                1.0,
                crate::physics::RefractiveIndex::new(0.13, 3.4),
                mu,
            )
            .unwrap()
        };
        for m in [0, 1] {
            let (a, g, _) = slab(0.6, 0.9, m);
            let mq = crate::solver::orders::mirror_blocks(&g.mu_q, g.ns, &fresnel);
            let mu_blocks = crate::solver::orders::mirror_blocks(&g.mu_u, g.ns, &fresnel);
            let top = add_mirror(&a, &mq, &mu_blocks);
            let mut base = Ops::reflector(a.n, a.nu, g.ns);
            base.r = mq.clone();
            let added = add(&a, &base, true);
            let d = max_abs((&top.r - &added.r).as_ref());
            let scale = max_abs(added.r.as_ref());
            assert!(d <= 1e-13 * scale, "m = {m}: {d:e} of {scale:e}");
            let empty = Ops::vacuum(a.n, a.nu, g.ns);
            let bare = add_mirror(&empty, &mq, &mu_blocks);
            assert!(max_abs((&bare.r - &mq).as_ref()) == 0.0);
            assert!(
                max_abs(bare.ruu.as_ref()) <= 1e-300,
                "no diffuse user light from a bare mirror"
            );
        }
    }

    #[test]
    fn source_weights_limits() {
        // Small h: a0 = h/2 − h²/6 + …, a1 = h/2 − h²/3 + … (Taylor).
        let h = 1e-3;
        let (a0, a1) = linear_source_weights(h);
        assert!((a0 - (h / 2.0 - h * h / 6.0 + h * h * h / 24.0)).abs() < 1e-13);
        assert!((a1 - (h / 2.0 - h * h / 3.0 + h * h * h / 8.0)).abs() < 1e-13);
        // Continuity across the series/closed-form switch.
        let (b0, b1) = linear_source_weights(0.1 - 1e-12);
        let (c0, c1) = linear_source_weights(0.1 + 1e-12);
        // (h differs by 2e-12 and the weights have slopes below 1.)
        assert!((b0 - c0).abs() < 3e-12 && (b1 - c1).abs() < 3e-12);
        // Large h: the source at the face dominates.
        let (d0, d1) = linear_source_weights(1e4);
        assert!((d0 - (1.0 - 1e-4)).abs() < 1e-12 && (d1 - 1e-4).abs() < 1e-12);
    }

    #[test]
    fn divided_difference_limits() {
        let v = exp_divided_difference(0.3, 2.0, 2.0);
        assert!((v - 0.3 * (-0.6f64).exp()).abs() < 1e-15);
        let exact = ((-0.3 * 2.0f64).exp() - (-0.3 * 5.0f64).exp()) / 3.0;
        assert!((exp_divided_difference(0.3, 2.0, 5.0) - exact).abs() < 1e-15);
        assert!((exp_divided_difference(0.3, 5.0, 2.0) - exact).abs() < 1e-15);
    }
}
