//! Helpers shared by the integration tests: reading the vendored benchmark tables
//! (`tests/data/benchmarks`, each with its source and citation).
#![allow(dead_code)]

pub mod ggx;

use polbrdf::physics::expansion::GreekCoefficients;
use serde_json::Value;

/// Parse a vendored benchmark file from `tests/data/benchmarks`.
pub fn benchmark(name: &str) -> Value {
    let path = format!(
        "{}/tests/data/benchmarks/{name}",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("benchmark file {path} is required by this test: {e}"));
    serde_json::from_str(&text).expect("benchmark JSON")
}

/// `Value` array of numbers to `Vec<f64>`.
pub fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .expect("array")
        .iter()
        .map(|x| x.as_f64().expect("number"))
        .collect()
}

/// The Garcia–Siewert L=13 coefficients (Siewert/VLIDORT convention).
pub fn garcia_siewert() -> GreekCoefficients {
    let v = benchmark("garcia_siewert_L13_coeffs.json");
    let c = &v["coefficients"];
    GreekCoefficients {
        beta: floats(&c["beta"]),
        alpha: floats(&c["alpha"]),
        zeta: floats(&c["zeta"]),
        delta: floats(&c["delta"]),
        gamma: floats(&c["gamma"]),
        epsilon: floats(&c["epsilon"]),
    }
}

/// Track the worst deviation of a comparison and where it happened.
#[derive(Default, Debug)]
pub struct Worst {
    pub value: f64,
    pub at: String,
    pub count: usize,
}

impl Worst {
    pub fn see(&mut self, dev: f64, at: impl FnOnce() -> String) {
        self.count += 1;
        if dev > self.value || !dev.is_finite() {
            self.value = dev;
            self.at = at();
        }
    }
}

/// Largest absolute difference of two Mueller matrices.
pub fn max_diff(a: &[[f64; 4]; 4], b: &[[f64; 4]; 4]) -> f64 {
    a.iter()
        .flatten()
        .zip(b.iter().flatten())
        .fold(0.0, |m, (x, y)| m.max((x - y).abs()))
}

/// The reciprocal partner `Δ gᵀ Δ`, `Δ = diag(1, 1, −1, 1)` (conventions §5).
pub fn reversed(g: &[[f64; 4]; 4]) -> [[f64; 4]; 4] {
    let d = [1.0, 1.0, -1.0, 1.0];
    let mut o = [[0.0; 4]; 4];
    for i in 0..4 {
        for j in 0..4 {
            o[i][j] = d[i] * g[j][i] * d[j];
        }
    }
    o
}

/// Run the real `polbrdf` binary: (exit code, stdout, stderr).
pub fn run(args: &[&str]) -> (i32, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_polbrdf"))
        .args(args)
        .output()
        .expect("run polbrdf");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Run `polbrdf`, require exit code 0 and return the JSON it printed.
pub fn ok(args: &[&str]) -> Value {
    let (code, out, err) = run(args);
    assert_eq!(code, 0, "polbrdf {args:?}: {err}");
    serde_json::from_str(&out).expect("JSON on stdout")
}

/// `polbrdf solve SPEC --points POINTS` (both file paths): the Mueller
/// matrix of each point at the first wavelength, in the points' order.
pub fn solve_points(spec: &str, points: &str) -> Vec<[[f64; 4]; 4]> {
    let v = ok(&["solve", spec, "--points", points]);
    v["results"][0]["points"]
        .as_array()
        .expect("points in the first result")
        .iter()
        .map(|p| {
            let mut m = [[0.0; 4]; 4];
            for (i, row) in m.iter_mut().enumerate() {
                for (j, x) in row.iter_mut().enumerate() {
                    *x = p["mueller"][i][j].as_f64().expect("a number");
                }
            }
            m
        })
        .collect()
}

/// A fresh scratch directory `polbrdf-tests/<name>-<pid>-<k>` under the
/// system temporary directory. Paths into it outlive any guard the tests
/// could hold, so instead the first call of each test process removes the
/// directories of test processes that have exited (where `/proc` tells).
pub fn scratch_dir(name: &str) -> std::path::PathBuf {
    static COUNTER: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    static PRUNED: std::sync::Once = std::sync::Once::new();
    let root = std::env::temp_dir().join("polbrdf-tests");
    PRUNED.call_once(|| prune_exited(&root));
    let k = COUNTER.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
    let d = root.join(format!("{name}-{}-{k}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Remove `<name>-<pid>-<k>` directories under `root` whose process is gone.
fn prune_exited(root: &std::path::Path) {
    if !std::path::Path::new("/proc/self").exists() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(root) else {
        return;
    };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let pid = name.rsplit('-').nth(1).and_then(|p| p.parse::<u32>().ok());
        if let Some(pid) = pid
            && pid != std::process::id()
            && !std::path::Path::new(&format!("/proc/{pid}")).exists()
        {
            let _ = std::fs::remove_dir_all(e.path());
        }
    }
}

/// The probe of docs/accuracy.md and `polbrdf convergence` (its own grid).
pub fn probe_grid() -> (Vec<f64>, Vec<f64>) {
    polbrdf::cli::convergence::probe_grid()
}

/// `polbrdf solve` of `spec` (written to `bad.json` in the scratch
/// directory `name`): it must be refused as bad input (exit code 2); its
/// stderr.
pub fn refused(name: &str, spec: &Value) -> String {
    let p = scratch_dir(name).join("bad.json");
    std::fs::write(&p, serde_json::to_string(spec).unwrap()).unwrap();
    let (code, _, err) = run(&["solve", p.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    err
}
