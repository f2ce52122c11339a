//! The Python package (`python/`, docs/python.md) built and tested as a user
//! gets it: a wheel built from the source tree by pip (maturin, the Rust
//! toolchain and nothing else), installed into a virtual environment with the
//! real Mitsuba 3 from PyPI, then its pytest suite `python/tests`:
//!
//! * `test_api.py`: `polbrdf.mie`, `solve`, `Table.load`/`eval`/`specular`
//!   against the `polbrdf` binary this test run built (exact equality), the
//!   Rayleigh limit of Mie theory, a Lambertian base's albedo, spec errors
//!   with their field paths, the GIL released during a solve;
//! * `test_client.py`: `polbrdf.Client` against `polbrdf serve` (submit,
//!   wait with progress, fetch through the render-node cache, refusals);
//! * `test_mitsuba.py`: the Mitsuba plugin's `eval` against `polbrdf eval`
//!   in Mitsuba's frames (1e-6 of max f11), its delta lobe and a path-traced
//!   mirror sphere against Mitsuba's `conductor`, the chi-square test of its
//!   sampling, sample weights = eval / pdf in both transport modes, and a
//!   sphere against `measured_polarized`, in `scalar_spectral_polarized` and
//!   `llvm_ad_spectral_polarized` (which needs libLLVM 19: `.ci/run`
//!   installs Debian's `libllvm19`).
//!
//! The virtual environment `target/python-venv` is made on first use (in a
//! temporary directory, renamed into place). Without `python3` the test is
//! skipped with a loud message, and under `CI` it fails instead; the pytest
//! suite likewise skips the LLVM variant loudly without libLLVM 19 and fails
//! under `CI`. Run time: about 3 minutes the first time (the wheel's build
//! and the install), then about a minute.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// The Mitsuba release the plugin was checked against (as tests/mitsuba_export.rs).
const MITSUBA_VERSION: &str = "3.9.1";

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The build directory: the run's own (`CARGO_TARGET_DIR`), so the wheel's
/// build reuses the `polbrdf` library this run compiled.
fn target_dir() -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo().join("target"))
}

fn run(cmd: &mut Command, what: &str) {
    let t0 = Instant::now();
    let st = cmd
        .status()
        .unwrap_or_else(|e| panic!("{what}: cannot start: {e}"));
    assert!(st.success(), "{what} failed ({st})");
    eprintln!(
        "python_package: {what}: {:.1} s",
        t0.elapsed().as_secs_f64()
    );
}

fn has_python3() -> bool {
    Command::new("python3")
        .arg("--version")
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false)
}

fn venv_ready(py: &Path) -> bool {
    let check = format!(
        "import mitsuba, maturin, numpy, pytest, sys; sys.exit(mitsuba.__version__ != '{MITSUBA_VERSION}')"
    );
    Command::new(py)
        .args(["-c", &check])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false)
}

/// `target/python-venv` with maturin, numpy, pytest and Mitsuba.
fn venv() -> PathBuf {
    let venv = repo().join("target").join("python-venv");
    let py = venv.join("bin").join("python");
    if venv_ready(&py) {
        return py;
    }
    let tmp = repo()
        .join("target")
        .join(format!("python-venv.tmp{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(repo().join("target")).unwrap();
    run(
        Command::new("python3").args(["-m", "venv", tmp.to_str().unwrap()]),
        "python3 -m venv",
    );
    run(
        Command::new(tmp.join("bin").join("python")).args([
            "-m",
            "pip",
            "install",
            "--quiet",
            "--disable-pip-version-check",
            "maturin>=1.7,<2",
            "numpy",
            "pytest",
            &format!("mitsuba=={MITSUBA_VERSION}"),
        ]),
        "pip install maturin numpy pytest mitsuba",
    );
    let _ = std::fs::remove_dir_all(&venv);
    if std::fs::rename(&tmp, &venv).is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    assert!(venv_ready(&py), "{} lacks the test packages", py.display());
    py
}

/// `PATH` with the virtual environment's `bin` first (pip runs the build
/// backend's `maturin` command from there).
fn with_venv_bin(py: &Path) -> std::ffi::OsString {
    let bin = py.parent().expect("venv/bin").to_path_buf();
    let rest = std::env::var_os("PATH").unwrap_or_default();
    std::env::join_paths(std::iter::once(bin).chain(std::env::split_paths(&rest))).expect("a PATH")
}

/// The first libLLVM 19 of the system, for Dr.Jit's LLVM backend.
fn libllvm19() -> Option<PathBuf> {
    let dir = Path::new("/usr/lib/x86_64-linux-gnu");
    ["libLLVM-19.so", "libLLVM.so.19.1", "libLLVM-19.so.1"]
        .iter()
        .map(|n| dir.join(n))
        .find(|p| p.exists())
}

#[test]
fn python_package_builds_installs_and_passes_its_tests() {
    if !has_python3() {
        assert!(
            std::env::var_os("CI").is_none(),
            "python3 is missing under CI"
        );
        eprintln!(
            "\n\n!!!!!!!!!! SKIPPED: python3 is missing, so the Python package and the Mitsuba plugin are NOT tested !!!!!!!!!!\n\n"
        );
        return;
    }
    let py = venv();
    let wheels = target_dir().join("python-wheels");
    let _ = std::fs::remove_dir_all(&wheels);
    // A wheel from the source tree, as `pip install ./python` builds one.
    run(
        Command::new(&py)
            .args([
                "-m",
                "pip",
                "wheel",
                "--quiet",
                "--disable-pip-version-check",
                "--no-build-isolation",
                "--no-deps",
                "-w",
                wheels.to_str().unwrap(),
                repo().join("python").to_str().unwrap(),
            ])
            .env("CARGO_TARGET_DIR", target_dir())
            .env("PATH", with_venv_bin(&py)),
        "pip wheel ./python",
    );
    let wheel = std::fs::read_dir(&wheels)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|x| x == "whl"))
        .expect("a wheel");
    run(
        Command::new(&py).args([
            "-m",
            "pip",
            "install",
            "--quiet",
            "--disable-pip-version-check",
            "--force-reinstall",
            "--no-deps",
            wheel.to_str().unwrap(),
        ]),
        "pip install the wheel",
    );
    let mut pytest = Command::new(&py);
    pytest
        .args(["-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider"])
        .arg(repo().join("python").join("tests"))
        .current_dir(std::env::temp_dir())
        .env("POLBRDF_BIN", env!("CARGO_BIN_EXE_polbrdf"));
    if let Some(lib) = libllvm19() {
        pytest.env("DRJIT_LIBLLVM_PATH", lib);
    }
    run(&mut pytest, "pytest python/tests");
}
