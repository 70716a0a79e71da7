//! Uniform resampling of a point cloud at spacing ε (thesis 5.3.1): keeps a subset of the input
//! points, with their normals, colours and attributes ([`PointCloud::select`]).
//!
//! The thesis gives ε relative to the scene's diagonal (5.4: 0.0005 for scanned objects, 0.00005
//! for city scans); this API takes an absolute spacing, so pass `ε_rel × cloud.diagonal()`.

use std::collections::HashMap;

use serde::{Deserialize, Serialize};

use crate::point_cloud::PointCloud;
use crate::sampling::poisson_disc::{
    CandidateOrder, Constraints, PoissonDiscOptions, Spacing, poisson_disc_points,
};
use crate::{Error, Result};

/// How the kept points are chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ResampleMethod {
    /// Poisson-disc elimination at radius ε in a seeded random order: no two kept points closer
    /// than ε, every input point closer than ε to a kept one (blue noise).
    PoissonDisc,
    /// One point per cube of side ε (the input point nearest to the mean of the cube's points):
    /// faster, but kept points may be closer than ε across cube faces.
    VoxelGrid,
}

/// Options of [`resample`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ResampleOptions {
    /// The spacing ε, in the cloud's units (absolute; thesis 5.3.1 and 5.4 give it relative to the
    /// diagonal); default 0.01.
    pub spacing: f64,
    /// Poisson-disc or voxel grid; default Poisson-disc.
    pub method: ResampleMethod,
    /// Seed of the Poisson-disc candidate order; default 0.
    pub seed: u64,
}

impl Default for ResampleOptions {
    fn default() -> Self {
        ResampleOptions { spacing: 0.01, method: ResampleMethod::PoissonDisc, seed: 0 }
    }
}

/// A resampled cloud and where its points come from.
#[derive(Debug, Clone, PartialEq)]
pub struct Resampled {
    /// The kept points with all their per-point data, in input order.
    pub cloud: PointCloud,
    /// Input index of every kept point, ascending.
    pub indices: Vec<usize>,
}

/// Resamples `cloud` uniformly at spacing ε; deterministic for a seed.
pub fn resample(cloud: &PointCloud, options: &ResampleOptions) -> Result<Resampled> {
    cloud.validate()?;
    let eps = options.spacing;
    if !(eps.is_finite() && eps > 0.0) {
        return Err(Error::InvalidOption {
            name: "spacing",
            message: format!("must be positive and finite, got {eps}"),
        });
    }
    let mut indices = match options.method {
        ResampleMethod::PoissonDisc => {
            let o = PoissonDiscOptions {
                spacing: Spacing::Radius(eps),
                seed: options.seed,
                order: CandidateOrder::Random,
                ..Default::default()
            };
            poisson_disc_points(&cloud.positions, None, &Constraints::default(), &o)?.candidate_indices()
        }
        ResampleMethod::VoxelGrid => voxel_representatives(cloud, eps),
    };
    indices.sort_unstable();
    Ok(Resampled { cloud: cloud.select(&indices), indices })
}

/// Per occupied voxel, the point nearest to the mean of the voxel's points (lowest index on ties).
fn voxel_representatives(cloud: &PointCloud, eps: f64) -> Vec<usize> {
    let inv = 1.0 / eps;
    let key = |p: [f64; 3]| p.map(|c| (c * inv).floor() as i64);
    let mut cells: HashMap<[i64; 3], (usize, [f64; 3])> = HashMap::new();
    let mut cell_of = Vec::with_capacity(cloud.len());
    for p in &cloud.positions {
        let k = key(*p);
        let e = cells.entry(k).or_insert((0, [0.0; 3]));
        e.0 += 1;
        for a in 0..3 {
            e.1[a] += p[a];
        }
        cell_of.push(k);
    }
    let mut best: HashMap<[i64; 3], (f64, usize)> = HashMap::with_capacity(cells.len());
    for (i, p) in cloud.positions.iter().enumerate() {
        let (n, s) = cells[&cell_of[i]];
        let mean = s.map(|c| c / n as f64);
        let d = crate::geometry::dist2(*p, mean);
        let e = best.entry(cell_of[i]).or_insert((d, i));
        if d < e.0 {
            *e = (d, i);
        }
    }
    best.into_values().map(|(_, i)| i).collect()
}
