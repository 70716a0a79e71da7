//! Symmetry-preserving real-time deformation (thesis chapter 3, Wu et al. 2014b).
//!
//! This crate's place in the workspace is fixed now; its algorithms land with the deformation
//! issue: symmetry annotations (`motif_symmetry_v1`), symmetric Poisson-disc sampling (3.4), the
//! symmetry-preserving basis and its lifting to the mesh, co-rotated Laplace editing (3.5), and a
//! `DeformSession` (precompute once, solve per frame). It depends on `motif-core` only.

#![warn(missing_docs)]

/// The thesis chapter this crate implements, for reports and `--version` output.
pub const THESIS_CHAPTER: &str = "3: real-time symmetry-preserving deformation";

pub mod symmetry_detect;
