//! Motif detect (placeholder crate; see ARCHITECTURE.md)
