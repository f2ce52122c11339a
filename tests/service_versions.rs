//! Results of an older solver version are never served (docs/service.md,
//! "Ids and versions"): a data directory written by a version-2 service
//! (the schema of migrations/0001 only, ids hashed with `polbrdf-solver/2`)
//! is opened by the current binary, which must answer 410 for those ids,
//! name the id of the same spec under the current version, leave an old
//! queued job unsolved, and compute the spec afresh when it is submitted.

mod service_support;

use serde_json::Value;
use service_support::*;
use sqlx::Connection;
use std::time::Duration;

/// The id a version-2 service gave a canonical spec (docs/service.md, step 3).
fn v2_id(canonical: &str) -> String {
    sha256_hex(format!("polbrdf-spec/1\npolbrdf-solver/2\n{canonical}").as_bytes())
}

/// Create the index as a version-2 service left it: migration 0001 applied
/// (recorded by sqlx as the embedded copy would be), then one done and one
/// queued row with version-2 ids.
async fn old_data_dir(data: &std::path::Path, done: &str, queued: &str) {
    std::fs::create_dir_all(data.join("blobs")).unwrap();
    let only_first = data.with_extension("migrations");
    std::fs::create_dir_all(&only_first).unwrap();
    std::fs::copy(
        concat!(env!("CARGO_MANIFEST_DIR"), "/migrations/0001_init.sql"),
        only_first.join("0001_init.sql"),
    )
    .unwrap();
    let url = format!(
        "sqlite://{}?mode=rwc",
        data.join("polbrdf.sqlite").display()
    );
    let mut conn = sqlx::SqliteConnection::connect(&url).await.unwrap();
    sqlx::migrate::Migrator::new(only_first.as_path())
        .await
        .unwrap()
        .run(&mut conn)
        .await
        .unwrap();
    for (spec, status) in [(done, "done"), (queued, "queued")] {
        let digest = "0".repeat(64);
        sqlx::query(
            "INSERT INTO jobs (id, status, spec, wavelengths, progress, digest, size, media_type,
                               created_at, updated_at)
             VALUES (?1, ?2, ?3, 1, ?4, ?5, ?6, ?7, 1, 1)",
        )
        .bind(v2_id(spec))
        .bind(status)
        .bind(spec)
        .bind(if status == "done" { 1.0 } else { 0.0 })
        .bind((status == "done").then_some(digest))
        .bind((status == "done").then_some(100i64))
        .bind((status == "done").then_some("application/vnd.polbrdf.table; version=3"))
        .execute(&mut conn)
        .await
        .unwrap();
    }
    conn.close().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn results_of_an_older_solver_version_are_not_served() {
    let dir = TempDir::new("versions");
    let data = dir.0.join("data");
    let c = client();

    // The canonical JSON of two specs, as the current service writes them.
    let probe = Server::start(&dir.0.join("probe"), &[], &[]);
    let queued_spec = slow_spec(1, 0.42);
    let mut canon = Vec::new();
    for spec in [TINY, queued_spec.as_str()] {
        let (code, v, _) = post(&c, &probe, spec).await;
        assert!(code == 200 || code == 202, "{v}");
        let id = v["id"].as_str().unwrap().to_string();
        let done = wait_done(&c, &probe, &id).await;
        canon.push((id, done["spec"].clone()));
    }
    drop(probe);
    let canonical: Vec<String> = canon
        .iter()
        .map(|(_, s)| {
            let mut out = String::new();
            polbrdf::material::canonical::write_canonical(s, &mut out);
            out
        })
        .collect();
    // The current id is the hash of the same text under the current version.
    for ((id, _), text) in canon.iter().zip(&canonical) {
        assert_eq!(&polbrdf::plan::id_of_canonical(text), id);
    }
    old_data_dir(&data, &canonical[0], &canonical[1]).await;
    let (old_done, old_queued) = (v2_id(&canonical[0]), v2_id(&canonical[1]));

    let s = Server::start(&data, &[], &[]);
    for (old, (current, _)) in [(&old_done, &canon[0]), (&old_queued, &canon[1])] {
        assert_ne!(old, current);
        for route in [
            "",
            "/table",
            "/eval?theta_i_deg=0&phi_i_deg=0&theta_o_deg=0&phi_o_deg=0",
        ] {
            let r = c
                .get(s.url(&format!("/v1/brdfs/{old}{route}")))
                .send()
                .await
                .unwrap();
            assert_eq!(r.status().as_u16(), 410, "route {route:?}");
            let p: Value = r.json().await.unwrap();
            assert_eq!(p["status"], 410);
            let detail = p["detail"].as_str().unwrap();
            assert!(detail.contains("polbrdf-solver/2"), "{detail}");
            assert!(detail.contains(current.as_str()), "{detail}");
        }
    }
    // The old queued row is not solved at start-up.
    tokio::time::sleep(Duration::from_millis(500)).await;
    let url = format!("sqlite://{}", data.join("polbrdf.sqlite").display());
    let mut conn = sqlx::SqliteConnection::connect(&url).await.unwrap();
    let status: String = sqlx::query_scalar("SELECT status FROM jobs WHERE id = ?")
        .bind(&old_queued)
        .fetch_one(&mut conn)
        .await
        .unwrap();
    assert_eq!(status, "queued");
    conn.close().await.unwrap();
    // Submitting the spec computes it under the current version.
    let (code, v, _) = post(&c, &s, TINY).await;
    assert_eq!(code, 202, "a retired result must not count as cached: {v}");
    assert_eq!(v["id"], canon[0].0.as_str());
    let done = wait_done(&c, &s, &canon[0].0).await;
    assert_eq!(done["status"], "done");
}
