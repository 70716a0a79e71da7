//! Motif retarget (placeholder crate; see ARCHITECTURE.md)
