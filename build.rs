//! Rebuild when a migration changes: `sqlx::migrate!()` embeds migrations/
//! into the binary at compile time (src/storage/index.rs).
fn main() {
    println!("cargo:rerun-if-changed=migrations");
}
