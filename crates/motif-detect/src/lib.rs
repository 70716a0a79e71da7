//! Approximate partial symmetry detection by co-occurrence analysis (thesis chapter 5,
//! Li et al. 2015).
//!
//! This crate's place in the workspace is fixed now; its algorithms land with the detection
//! issue: curvature features and the HOC descriptor (5.3.1, 5.4), the dictionary, EM
//! co-occurrence voting (5.3.2), spectral grouping into instances (5.3.3), MDL incremental
//! detection, and the evaluation protocol of 5.5.2. It depends on `motif-core` only.
//!
//! Available now:
//! - [`detection`]: the detection / ground-truth JSON schema (`../shared/formats/detection.md`),
//!   read, written and validated;
//! - [`class_merge`]: classes of one block found in different MDL rounds joined again (not in
//!   the thesis);
//! - [`extent`]: instance extents by segmentation and classes regrouped by size (not in the
//!   thesis);
//! - [`content`]: instances reassigned to classes by depth images of their surroundings (not in
//!   the thesis; a step of the extent stage);
//! - [`aligned`]: instances reassigned again by depth images at one common scale, compared at
//!   the best shift (not in the thesis; the extent stage's last step);
//! - [`segment_classes`]: classes of unexplained segments repeated by size (not in the thesis;
//!   a step of the extent stage);
//! - [`eval`]: the evaluation protocol of thesis 5.5.2 (box matching, precision, recall, F, the
//!   PR curve by class removal and the stress curve over the overlap threshold τ);
//! - [`plot`]: the PR and stress curves as a PNG (like the thesis's Fig. 5.9);
//! - [`mod@rigid_icp`]: the supervised rigid-ICP sliding-window baseline of 5.5.3;
//! - [`scenes`]: benchmark point clouds of facades and streets with ground truth, at graded
//!   difficulty.

#![warn(missing_docs)]

pub mod aligned;
pub mod class_merge;
pub mod communities;
pub mod content;
pub mod cooccurrence;
pub mod copies;
pub mod detection;
pub mod dictionary;
pub mod error;
pub mod eval;
pub mod extent;
pub mod grid;
pub mod hoc;
pub mod instances;
pub mod pipeline;
pub mod plot;
pub mod preprocess;
pub mod refine;
pub mod rigid_icp;
pub mod scenes;
pub mod segment_classes;
pub mod shape_split;

pub use detection::{DetectedClass, DetectedInstance, DetectionResult};
pub use error::{DetectError, Result};
pub use eval::{
    AnnotatedClassReport, AnnotatedClassTotals, DetectedClassReport, EvalOptions, EvalReport, EvalSummary,
    evaluate, evaluate_many,
};
pub use pipeline::{DetectOptions, DetectReport, Detection, Method, detect, detect_mesh};
pub use plot::{BenchRow, EvalCurves, plot_bench, plot_pr_and_stress, plot_pr_and_stress_titled};
pub use rigid_icp::{ClassCompetition, RigidIcpOptions, RigidIcpReport, rigid_icp};
pub use scenes::{Difficulty, Scene, SceneKind, SceneOptions, generate_scene};

/// The thesis chapter this crate implements, for reports and `--version` output.
pub const THESIS_CHAPTER: &str = "5: approximate 3D partial symmetry detection by co-occurrence analysis";
