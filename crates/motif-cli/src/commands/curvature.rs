//! `motif curvature`: principal curvatures and directions, as PLY properties or CSV.

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use motif_core::curvature::{
    CurvatureOptions, CurvatureStatus, Neighbourhood, PrincipalCurvature, principal_curvatures_mesh,
    principal_curvatures_points,
};
use motif_core::{AttributeData, TriMesh};
use serde::Serialize;

use crate::cli::{CurvatureArgs, GlobalArgs};
use crate::output::{bad_input, maybe_json, ms_since};

/// Smallest, median and largest value over the fitted points.
#[derive(Debug, Serialize)]
struct Summary {
    min: f64,
    median: f64,
    max: f64,
}

#[derive(Debug, Serialize)]
struct CurvatureReport {
    input: String,
    output: String,
    points: usize,
    neighbourhood: String,
    fitted: usize,
    not_fitted: usize,
    k1: Summary,
    k2: Summary,
    sign_convention: &'static str,
    ms: f64,
}

fn summary(mut v: Vec<f64>) -> Summary {
    if v.is_empty() {
        return Summary { min: 0.0, median: 0.0, max: 0.0 };
    }
    v.sort_by(|a, b| a.total_cmp(b));
    Summary { min: v[0], median: v[v.len() / 2], max: v[v.len() - 1] }
}

pub fn run(a: CurvatureArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    crate::output::check_outputs(&[Some(a.output()), a.json.json.as_deref()], &[&a.input], g.force)?;
    let ext = a.output().extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
    if !matches!(ext.as_deref(), Some("ply" | "csv")) {
        return Err(bad_input(format!(
            "{}: curvature is written as PLY (vertex properties k1, k2, d1, d2) or CSV; other formats \
             cannot hold it",
            a.output().display()
        )));
    }
    let mut model = super::read_model_for_geometry(&a.input)?;
    let neighbourhood = match (a.k, a.radius) {
        (_, Some(r)) if !(r > 0.0 && r.is_finite()) => {
            return Err(bad_input(format!("--radius {r}: must be a positive number")));
        }
        (_, Some(r)) => Neighbourhood::Radius(r),
        (Some(k), None) if k < 6 => {
            return Err(bad_input(format!("-k {k}: a quadratic fit needs at least 6 neighbours")));
        }
        (Some(k), None) if k > 1000 => {
            return Err(bad_input(format!("-k {k}: use at most 1000 neighbours (the default is 15)")));
        }
        (Some(k), None) => Neighbourhood::Knn(k),
        (None, None) => Neighbourhood::Knn(15),
    };
    let options = CurvatureOptions { neighbourhood, ..Default::default() };
    let t = Instant::now();
    let bar = crate::progress::Bar::new(g.quiet);
    let pc: Vec<PrincipalCurvature> = bar.spin("curvature", || {
        if model.is_mesh() {
            let mesh =
                TriMesh { positions: model.vertices.positions.clone(), triangles: model.triangles.clone() };
            principal_curvatures_mesh(&mesh, &options)
        } else {
            principal_curvatures_points(
                &model.vertices.positions,
                model.vertices.normals.as_deref(),
                &options,
            )
        }
    })?;
    let ms = ms_since(t);
    let described = match neighbourhood {
        Neighbourhood::Radius(r) => crate::output::tidy_numbers(&format!("radius {r}")),
        Neighbourhood::Knn(k) => format!("{k} nearest points"),
        Neighbourhood::Rings(n) => format!("{n} rings"),
    };
    let fitted = pc.iter().filter(|c| c.status == CurvatureStatus::Fitted).count();
    // Nothing fitted is a failure, not a file of zeros (it used to exit 0 with one).
    if fitted == 0 && !pc.is_empty() {
        return Err(bad_input(format!(
            "{}: no point could be fitted: no neighbourhood ({described}) holds enough points for a \
             quadratic (6 or more, spread over the surface); use a larger --radius or -k",
            a.input.display()
        )));
    }
    if fitted < pc.len() {
        super::warn(format!(
            "{} of {} points ({:.0}%) could not be fitted ({described}): their k1 and k2 are 0, marked \
             by the status column (CSV) or the `fitted` property (PLY), and left out of the medians",
            pc.len() - fitted,
            pc.len(),
            100.0 * (pc.len() - fitted) as f64 / pc.len() as f64
        ));
    }
    let is_csv = a.output().extension().is_some_and(|e| e.eq_ignore_ascii_case("csv"));
    if is_csv {
        write_csv(a.output(), &model.vertices.positions, &pc)?;
    } else {
        let v = &mut model.vertices;
        let col = |f: &dyn Fn(&PrincipalCurvature) -> f64| AttributeData::Float(pc.iter().map(f).collect());
        v.set_attribute("k1", col(&|c| c.k1));
        v.set_attribute("k2", col(&|c| c.k2));
        for (i, axis) in ["x", "y", "z"].iter().enumerate() {
            v.set_attribute(&format!("d1{axis}"), col(&|c| c.d1[i]));
        }
        for (i, axis) in ["x", "y", "z"].iter().enumerate() {
            v.set_attribute(&format!("d2{axis}"), col(&|c| c.d2[i]));
        }
        v.set_attribute(
            "fitted",
            AttributeData::Int(pc.iter().map(|c| i64::from(c.status == CurvatureStatus::Fitted)).collect()),
        );
        if v.normals.is_none() {
            v.normals = Some(pc.iter().map(|c| c.normal).collect());
        }
        super::write_model(a.output(), &model, &[&a.input], g, &a.encoding)?;
    }
    let fitted_only = |f: fn(&PrincipalCurvature) -> f64| {
        summary(pc.iter().filter(|c| c.status == CurvatureStatus::Fitted).map(f).collect())
    };
    let r = CurvatureReport {
        input: a.input.display().to_string(),
        output: a.output().display().to_string(),
        points: pc.len(),
        neighbourhood: described,
        fitted,
        not_fitted: pc.len() - fitted,
        k1: fitted_only(|c| c.k1),
        k2: fitted_only(|c| c.k2),
        sign_convention: "k1 >= k2; positive where the surface bends away from the (outward) normal",
        ms,
    };
    if !crate::output::json_on_stdout(&a.json.json) {
        super::written(
            g,
            &r.output,
            format!(
                "{} points, {} fitted; median k1 {:.4}, k2 {:.4}; {:.1} ms",
                r.points, r.fitted, r.k1.median, r.k2.median, r.ms
            ),
        );
    }
    maybe_json(&a.json.json, &r)
}

fn write_csv(path: &Path, positions: &[[f64; 3]], pc: &[PrincipalCurvature]) -> anyhow::Result<()> {
    motif_core::io::write_atomic(path, |w| {
        let mut w = std::io::BufWriter::new(w);
        writeln!(w, "index,x,y,z,k1,k2,d1x,d1y,d1z,d2x,d2y,d2z,nx,ny,nz,status")?;
        for (i, (p, c)) in positions.iter().zip(pc).enumerate() {
            writeln!(
                w,
                "{i},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                p[0],
                p[1],
                p[2],
                c.k1,
                c.k2,
                c.d1[0],
                c.d1[1],
                c.d1[2],
                c.d2[0],
                c.d2[1],
                c.d2[2],
                c.normal[0],
                c.normal[1],
                c.normal[2],
                c.status.as_str()
            )?;
        }
        w.flush()
    })?;
    Ok(())
}
