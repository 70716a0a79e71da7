//! Structure-aware retargeting by offset statistics and graph cuts (thesis chapter 4,
//! Wu et al. 2014a).
//!
//! This crate's place in the workspace is fixed now; its algorithms land with the retargeting
//! issue: offset statistics (4.2.1, 4.4), the offset-sparsity study (4.3), the voxel MRF over the
//! offset label space with alpha-expansion on a Boykov–Kolmogorov max-flow (4.2.2), and the dense
//! baseline (4.5). It depends on `motif-core` only.
//!
//! Implemented so far, the MRF machinery of section 4.2.2:
//! - [`mod@maxflow`]: Boykov–Kolmogorov max-flow / min-cut with search-tree reuse;
//! - [`mod@alpha_expansion`]: alpha-expansion over arbitrary graphs with per-edge pairwise callbacks;
//! - [`mod@mrf_grid`]: the shared `mrf_grid_v1` problem format (load, validate, solve, generate).
//!
//! Modules so far: [`offsets`] (offset statistics: dominant and principal offsets, 4.2.1, 4.4),
//! [`sparsity`] (the sparsity study, 4.3) and [`plot`] (their pictures), [`mod@retarget`]
//! (offset-based retargeting, 4.2.2, 4.4, and the dense-MRF baseline, 4.5).

#![warn(missing_docs)]

pub mod alpha_expansion;
pub mod error;
pub mod maxflow;
pub mod mrf_grid;
pub mod retarget;

pub use alpha_expansion::{
    AlphaExpansion, AlphaExpansionOptions, AlphaExpansionResult, CycleStrategy, LabelOrder, MrfEnergy,
    Termination, TieBreak, alpha_expansion, energy_of,
};
pub use error::{Error, Result};
pub use maxflow::{Capacity, Graph, Segment};
pub use mrf_grid::{Connectivity, GridProblem, GridSolution, InitLabels, generate_grid, solve_grid_file};

/// The thesis chapter this crate implements, for reports and `--version` output.
pub const THESIS_CHAPTER: &str = "4: 3D model retargeting using offset statistics";

pub mod offsets;
pub mod plot;
pub mod sparsity;
