//! The same bytes on every node (docs/service.md, "The same bytes on every
//! node"): a result solved on this machine's CPU (AVX-512 here, where the
//! solver's SIMD layer runs its AVX2 + FMA kernels) and the same spec
//! solved by the same binary on an emulated x86-64-v3 CPU without AVX-512
//! (`qemu-x86_64 -cpu Haswell`) are the same bytes, so the same digest and
//! ETag. Needs `POLBRDF_TEST_QEMU` (the `qemu-x86_64` of Debian's
//! qemu-user; .ci/run installs it): SKIPPED without it, a failure under
//! `CI=true`.

mod service_support;

use service_support::*;
use std::io::Write;
use std::time::Duration;

/// A Mie layer (the expansion, the layer operators and the secondary
/// correction all run), small enough to solve in emulation in a minute.
const SPEC: &str = r#"{"layers":[{"optical_thickness":1.0,"scatterer":{"mie":{"material":"TiO2",
  "radius_um":0.2,"host_index":1.5}}}],"base":{"lambertian":{"albedo":0.3}},
  "wavelengths_nm":[550],"solver":{"streams":8}}"#;

fn qemu() -> Option<String> {
    match std::env::var("POLBRDF_TEST_QEMU") {
        Ok(q) if !q.is_empty() => Some(q),
        _ if std::env::var("CI").as_deref() == Ok("true") => {
            panic!("CI=true but POLBRDF_TEST_QEMU is unset (.ci/run installs qemu-user)")
        }
        _ => {
            let _ = writeln!(
                std::io::stderr(),
                "SKIPPED: service_simd: set POLBRDF_TEST_QEMU=/usr/bin/qemu-x86_64 \
                 (Debian's qemu-user) to solve on an emulated CPU of another SIMD level"
            );
            None
        }
    }
}

async fn digest_of(s: &Server) -> String {
    let c = client();
    let (code, v, _) = post(&c, s, SPEC).await;
    assert!(code == 202 || code == 200, "{code} {v}");
    let id = v["id"].as_str().unwrap().to_string();
    let done = wait_for(&c, s, &id, Duration::from_secs(600), |v| {
        v["status"] == "done" || v["status"] == "failed"
    })
    .await;
    assert_eq!(done["status"], "done", "{done}");
    done["result"]["digest"].as_str().unwrap().to_string()
}

#[cfg(target_arch = "x86_64")]
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_result_is_the_same_bytes_on_another_x86_64_simd_level() {
    let Some(qemu) = qemu() else {
        return;
    };
    let dir = TempDir::new("simd");
    let native = Server::start(&dir.0.join("native"), &["--workers", "1"], &[]);
    let here = digest_of(&native).await;
    drop(native);
    let emulated = Server::start_under(
        &[qemu.as_str(), "-cpu", "Haswell"],
        &dir.0.join("haswell"),
        &["--workers", "1"],
        &[],
    );
    let there = digest_of(&emulated).await;
    assert_eq!(
        here, there,
        "the bytes of one id differ between SIMD levels"
    );
}
