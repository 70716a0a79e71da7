//! Motif deform (placeholder crate; see ARCHITECTURE.md)
