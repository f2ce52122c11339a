//! (stub)
#[derive(Clone, Copy, Debug)]
pub enum SizeDistribution {
    LogNormal { r_g_um: f64, sigma_g: f64 },
    Gamma { r_eff_um: f64, v_eff: f64 },
}
