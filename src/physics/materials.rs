//! (stub, filled in by its own commit)
