//! `motif sample`: random or Poisson-disc samples of a surface, or a Poisson-disc subset of a cloud.

use std::time::Instant;

use anyhow::Context;
use motif_core::PointCloud;
use motif_core::io::Model;
use motif_core::sampling::{
    Constraints, PoissonDiscOptions, Spacing, poisson_disc_cloud, poisson_disc_surface, sample_surface,
};
use serde::Serialize;

use crate::cli::{GlobalArgs, SampleArgs};
use crate::output::{bad_input, maybe_json, ms_since};

#[derive(Debug, Serialize)]
struct SampleReport {
    input: String,
    output: String,
    method: &'static str,
    requested_radius: Option<f64>,
    requested_count: Option<usize>,
    radius: Option<f64>,
    samples: usize,
    seed: u64,
    ms: f64,
}

/// Most samples without `--force`: 5·10⁷, the detector's limit on resampled points too.
const MAX_SAMPLES: usize = 50_000_000;

pub fn run(a: SampleArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    crate::output::check_outputs(&[Some(a.output()), a.json.json.as_deref()], &[&a.input], g.force)?;
    crate::output::check_output_formats(&[(Some(a.output()), crate::output::OutputKind::PointCloud)])?;
    if let Some(r) = a.radius {
        if !(r > 0.0 && r.is_finite()) {
            return Err(bad_input(format!("--radius {r}: must be a positive number")));
        }
    }
    if a.count == Some(0) {
        return Err(bad_input("--count 0: ask for at least one sample"));
    }
    if let Some(n) = a.count.filter(|&n| n > MAX_SAMPLES && !g.force) {
        return Err(bad_input(format!(
            "--count {n}: more than {MAX_SAMPLES} points (about 48 bytes each; pass --force to sample that \
             many anyway)"
        )));
    }
    let model = super::read_model_for_geometry(&a.input)?;
    let poisson = a.poisson || a.radius.is_some();
    let in_input = || format!("sampling {}", a.input.display());
    let t = Instant::now();
    let bar = crate::progress::Bar::new(g.quiet);
    let (cloud, method, radius) = bar.spin("sampling", || -> anyhow::Result<_> { Ok(if !poisson {
        let n = a.count.unwrap_or(0);
        if !model.is_mesh() {
            return Err(bad_input(format!(
                "{}: is a point cloud; random surface sampling needs a mesh (use --poisson to thin a cloud)",
                a.input.display()
            )));
        }
        let s = sample_surface(&model.mesh(), n, g.seed).with_context(in_input)?;
        let cloud = PointCloud { positions: s.points, normals: Some(s.normals), ..Default::default() };
        (cloud, "area-weighted random", None)
    } else {
        let spacing = match (a.radius, a.count) {
            (Some(r), _) => Spacing::Radius(r),
            (None, Some(n)) => Spacing::Count(n),
            (None, None) => return Err(bad_input("give --radius or --count")),
        };
        let options = PoissonDiscOptions { spacing, seed: g.seed, ..Default::default() };
        // The library's limit on candidates names its option; say it with the flag given.
        let flag = match spacing {
            Spacing::Radius(r) => format!("--radius {r}"),
            Spacing::Count(n) => format!("--count {n}"),
        };
        let in_flags = |e: motif_core::Error| match e {
            motif_core::Error::InvalidOption { name: "radius", message } => {
                bad_input(format!("{}: {flag}: {message}", a.input.display()))
            }
            e => anyhow::Error::new(e).context(in_input()),
        };
        if model.is_mesh() {
            let s = poisson_disc_surface(&model.mesh(), &Constraints::default(), &options).map_err(in_flags)?;
            let cloud = PointCloud { positions: s.positions, normals: s.normals, ..Default::default() };
            (cloud, "Poisson-disc on the surface", Some(s.radius))
        } else {
            let s = poisson_disc_cloud(&model.vertices, &Constraints::default(), &options).map_err(in_flags)?;
            let idx = s.candidate_indices();
            (model.vertices.select(&idx), "Poisson-disc subset of the cloud", Some(s.radius))
        }
    })})?;
    let ms = ms_since(t);
    let samples = cloud.len();
    super::write_model(a.output(), &Model::from_point_cloud(cloud), &[&a.input], g, &a.encoding)?;
    let r = SampleReport {
        input: a.input.display().to_string(),
        output: a.output().display().to_string(),
        method,
        requested_radius: a.radius,
        requested_count: a.count,
        radius,
        samples,
        seed: g.seed,
        ms,
    };
    if !crate::output::json_on_stdout(&a.json.json) {
        let rad = r.radius.map(|x| format!(", radius {x:.6}")).unwrap_or_default();
        super::written(
            g,
            &r.output,
            format!(
                "{}, {}{rad}, {:.1} ms",
                crate::output::count(r.samples, "sample", "samples"),
                r.method,
                r.ms
            ),
        );
    }
    maybe_json(&a.json.json, &r)
}
