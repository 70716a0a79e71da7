//! Sampling of surfaces and point clouds: seeded area-weighted random surface samples
//! ([`sample_surface`]), Poisson-disc sampling with forced samples and exclusion zones for
//! symmetric sampling (thesis 3.4; [`PoissonDiscSampler`], [`poisson_disc_surface`],
//! [`poisson_disc_points`]), and uniform resampling of point clouds at a spacing ε (thesis 5.3.1;
//! [`resample`]).
//!
//! Everything is deterministic for a seed and independent of the number of threads.

mod poisson_disc;
mod resample;
mod surface;

pub use poisson_disc::{
    CandidateOrder, Constraints, ForcedOutput, NO_FACE, PoissonDiscOptions, PoissonDiscSampler,
    PoissonDiscSamples, SampleKind, SampleSource, Spacing, outside_forced, poisson_disc_cloud,
    poisson_disc_points, poisson_disc_surface,
};
pub use resample::{ResampleMethod, ResampleOptions, Resampled, resample};
pub use surface::{SurfaceSamples, sample_surface};
