use polbrdf::physics::expansion::GreekCoefficients;
use polbrdf::solver::*;
use std::time::Instant;
fn main() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/benchmarks/garcia_siewert_L13_coeffs.json"
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let c = &v["coefficients"];
    let get = |k: &str| -> Vec<f64> {
        c[k].as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let coef = GreekCoefficients {
        beta: get("beta"),
        alpha: get("alpha"),
        zeta: get("zeta"),
        delta: get("delta"),
        gamma: get("gamma"),
        epsilon: get("epsilon"),
    };
    let streams: usize = std::env::args()
        .nth(1)
        .map(|s| s.parse().unwrap())
        .unwrap_or(16);
    let sf: f64 = std::env::args()
        .nth(2)
        .map(|s| s.parse().unwrap())
        .unwrap_or(1e-3);
    let mu: Vec<f64> = (0..51)
        .map(|k| (90.0f64 * k as f64 / 50.0).to_radians().cos().max(1e-6))
        .collect();
    let mut mu = mu;
    mu.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let p = Problem {
        layers: vec![Layer {
            thickness: Thickness::Finite(1.0),
            albedo: 0.99,
            coef,
        }],
        base: Base::Black,
        settings: Settings {
            streams,
            start_factor: sf,
            ..Settings::default()
        },
    };
    let t = Instant::now();
    let r = reflection(&p, &mu).unwrap();
    let dt = t.elapsed();
    let f = r.brdf(25, 30, 0.3);
    println!(
        "streams {streams} sf {sf}: {:.1} ms, orders {}, f11 {:.8e} f12 {:.6e}",
        dt.as_secs_f64() * 1e3,
        r.rho.len(),
        f[0][0],
        f[0][1]
    );
}
