//! Rebuild when a migration changes: `sqlx::migrate!()` and
//! `sqlx::migrate!("migrations/postgres")` embed migrations/ and
//! migrations/postgres/ into the binary at compile time
//! (src/storage/index/). Cargo watches a directory recursively.
fn main() {
    println!("cargo:rerun-if-changed=migrations");
}
