//! Offset statistics (thesis 4.2.1, 4.4) and the sparsity study (4.3): quality on procedural
//! shapes with known lattices, the no-repetition verdict, invariances, and real data from
//! `shared/data` when it is present.

use std::path::{Path, PathBuf};

use motif_core::Point3;
use motif_core::mesh::TriMesh;
use motif_core::procedural::generate;
use motif_core::progress::NoProgress;
use motif_retarget::offsets::{OffsetAnalysis, OffsetOptions, PrincipalOffset, Repetition, analyze_offsets};
use motif_retarget::sparsity::{SparsityOptions, model_sparsity};

fn norm(v: Point3) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// Relative distance of `v` to `p` up to sign.
fn rel_err(v: Point3, p: Point3) -> f64 {
    let d = [v[0] - p[0], v[1] - p[1], v[2] - p[2]];
    let s = [v[0] + p[0], v[1] + p[1], v[2] + p[2]];
    norm(d).min(norm(s)) / norm(p)
}

fn analyze(mesh: &TriMesh) -> OffsetAnalysis {
    analyze_offsets(mesh, &OffsetOptions::default(), &NoProgress).expect("analysis runs")
}

/// A UV sphere of radius 1 with `bump` times a smooth radial perturbation (0: a sphere; 0.25: an
/// irregular blob).
fn blob(bump: f64) -> TriMesh {
    let (nu, nv) = (96usize, 48usize);
    let mut pos = vec![[0.0, 0.0, 1.0]];
    for j in 1..nv {
        let th = std::f64::consts::PI * j as f64 / nv as f64;
        for i in 0..nu {
            let ph = std::f64::consts::TAU * i as f64 / nu as f64;
            let d = [th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()];
            let r = 1.0
                + bump
                    * ((3.0 * d[0] + 1.0).sin() * (2.0 * d[1] - 0.5).cos() + 0.5 * (5.0 * d[2]).sin() * d[0]);
            pos.push(d.map(|c| c * r));
        }
    }
    pos.push([0.0, 0.0, -1.0]);
    let south = pos.len() as u32 - 1;
    let id = |j: usize, i: usize| (1 + (j - 1) * nu + i % nu) as u32;
    let mut tri = Vec::new();
    for i in 0..nu {
        tri.push([0, id(1, i), id(1, i + 1)]);
        tri.push([id(nv - 1, i), south, id(nv - 1, i + 1)]);
    }
    for j in 1..nv - 1 {
        for i in 0..nu {
            tri.push([id(j, i), id(j + 1, i), id(j + 1, i + 1)]);
            tri.push([id(j, i), id(j + 1, i + 1), id(j, i + 1)]);
        }
    }
    TriMesh::new(pos, tri).expect("valid sphere")
}

/// The facade's windows are half a bay wide, so half a bay maps window edges onto window edges
/// and its overlap contrast is modest (about 0.12): the verdict must not hinge on where the
/// random samples fell (with the salient set drawn from the sparse feature samples it flipped
/// to "no repetition" for half of the seeds, and `motif retarget` refused the generated facade).
#[test]
fn facade_verdict_does_not_depend_on_the_sampling_seed() {
    let ex = generate("facade", 0).expect("example");
    for seed in 1..5 {
        let a = analyze_offsets(&ex.mesh, &OffsetOptions { seed, ..Default::default() }, &NoProgress)
            .expect("analysis runs");
        assert_eq!(a.repetition.kind, Repetition::Repetitive, "seed {seed}: {}", a.repetition.summary);
    }
}

#[test]
fn principal_offsets_are_the_known_cell_pitch() {
    for name in ["shelf", "facade", "fence", "shelf_sheared"] {
        let ex = generate(name, 0).expect("example");
        let a = analyze(&ex.mesh);
        assert!(!ex.structure.cell_pitch.is_empty(), "{name} has a lattice");
        for p in &ex.structure.cell_pitch {
            let (best, err) = a
                .principal
                .iter()
                .map(|v| (v, rel_err(v.offset_model, *p)))
                .min_by(|x, y| x.1.total_cmp(&y.1))
                .unwrap_or_else(|| panic!("{name}: no principal offset"));
            println!(
                "{name}: pitch {p:?} -> principal {:.5?} (support {}), relative error {:.2e}",
                best.offset_model, best.support, err
            );
            // The pitch itself, not a multiple: 2× would be a 100% error.
            assert!(
                err <= 0.02,
                "{name}: pitch {p:?}, closest principal {:?} is {:.1}% off",
                best.offset_model,
                100.0 * err
            );
            // The generated models repeat exactly, vertex for vertex: the offset is snapped to the
            // exact translation (ICP alone leaves 10⁻⁵–10⁻³).
            let snap = best.vertex_snap.unwrap_or_else(|| panic!("{name}: pitch {p:?} was not snapped"));
            assert!(snap.pairs >= 8, "{name}: {snap:?}");
            assert!(
                err <= 1e-9,
                "{name}: snapped offset {:?} is {err:.1e} off the pitch {p:?}",
                best.offset_model
            );
        }
        assert_eq!(a.repetition.kind, Repetition::Repetitive, "{name}: {}", a.repetition.summary);
        // At most three principal offsets, pairwise at least θ = π/3 apart.
        assert!(a.principal.len() <= 3);
        for (i, u) in a.principal.iter().enumerate() {
            for w in &a.principal[i + 1..] {
                let c = (u.offset[0] * w.offset[0] + u.offset[1] * w.offset[1] + u.offset[2] * w.offset[2])
                    / (u.length * w.length);
                assert!(
                    c.abs() <= 0.5 + 1e-9,
                    "{name}: principal offsets {:?} and {:?} too close",
                    u.offset,
                    w.offset
                );
            }
        }
    }
}

#[test]
fn shapes_without_repetition_get_the_no_repetition_verdict() {
    for (name, mesh) in [("sphere", blob(0.0)), ("blob", blob(0.25))] {
        let a = analyze(&mesh);
        println!("{name}: {}", a.repetition.summary);
        assert_eq!(a.repetition.kind, Repetition::NoRepetition, "{name}: {}", a.repetition.summary);
        assert!(!a.repetition.summary.is_empty());
    }
}

#[test]
fn offsets_follow_rigid_translation_and_scaling_of_the_model() {
    let ex = generate("fence", 0).expect("fence");
    let a = analyze(&ex.mesh);
    let mut moved = ex.mesh.clone();
    for p in &mut moved.positions {
        *p = [3.0 * p[0] + 10.0, 3.0 * p[1] - 4.0, 3.0 * p[2] + 0.5];
    }
    let b = analyze(&moved);
    assert_eq!(a.principal.len(), b.principal.len());
    for (u, v) in a.principal.iter().zip(&b.principal) {
        // Normalised offsets are the same; model offsets scale by 3.
        assert!(rel_err(u.offset, v.offset) < 1e-3, "{:?} vs {:?}", u.offset, v.offset);
        assert!(rel_err(u.offset_model.map(|c| 3.0 * c), v.offset_model) < 1e-3);
    }
    assert!((b.normalisation.scale * 3.0 - a.normalisation.scale).abs() < 1e-9);
}

/// `axis_order` lists the principal offsets by model axis, whatever the model's unit: at
/// 10⁻³ of its size the shelf's random sample gives the y pitch more support than the x pitch
/// (432 against 427; 386 against 420 at full size), and `--steps 2,1` then grew it the other way.
#[test]
fn principal_offsets_are_listed_by_model_axis_in_any_unit() {
    let ex = generate("shelf", 0).expect("shelf");
    for factor in [1.0, 1e-3, 7.3, 1e3] {
        let mut scaled = ex.mesh.clone();
        for p in &mut scaled.positions {
            *p = p.map(|c| c * factor);
        }
        let a = analyze(&scaled);
        let axes: Vec<usize> = a
            .axis_order
            .iter()
            .map(|&k| {
                let p = &a.principal[k];
                (0..3).max_by(|&i, &j| p.offset[i].abs().total_cmp(&p.offset[j].abs())).unwrap()
            })
            .collect();
        assert_eq!(
            axes,
            [0, 1],
            "×{factor}: {:?}",
            a.principal.iter().map(|p| (p.offset, p.support)).collect::<Vec<_>>()
        );
        // The picture numbers them the same way (p0 along x), not in the order of selection.
        let numbered: Vec<usize> =
            motif_retarget::plot::principal_numbering(&a).into_iter().map(|(_, k)| k).collect();
        assert_eq!(numbered, a.axis_order, "×{factor}");
    }
}

/// The principal offsets are given in the orientation retargeting grows along (largest-magnitude
/// component positive), so `motif offsets` and `motif retarget` print the same vectors. A shelf
/// turned 30° about z and 20° about x has its y pitch along (−0.5, 0.81, 0.29) up to sign: the
/// histogram's half-space (first coordinate positive) gave it as (0.5, −0.81, −0.29).
#[test]
fn principal_offsets_point_the_way_retargeting_grows() {
    let ex = generate("shelf", 0).expect("shelf");
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let (c2, s2) = (20f64.to_radians().cos(), 20f64.to_radians().sin());
    let mut turned = ex.mesh.clone();
    for p in &mut turned.positions {
        let q = [c * p[0] - s * p[1], s * p[0] + c * p[1], p[2]];
        *p = [q[0], c2 * q[1] - s2 * q[2], s2 * q[1] + c2 * q[2]];
    }
    for mesh in [&ex.mesh, &turned] {
        let a = analyze(mesh);
        assert_eq!(a.principal.len(), 2);
        let offsets: Vec<Point3> = a.principal.iter().map(|p| p.offset_model).collect();
        assert_eq!(motif_retarget::retarget::orient_offsets(&offsets), offsets);
        // The turned y pitch: its largest component is the y one, positive.
        assert!(offsets.iter().any(|v| v[1] > 0.5 * norm(*v)), "{offsets:?}");
    }
}

#[test]
fn analysis_round_trips_through_json_and_options_default_from_empty_json() {
    let ex = generate("shelf", 0).expect("shelf");
    let a = analyze(&ex.mesh);
    let text = serde_json::to_string(&a).expect("serialise");
    let back: OffsetAnalysis = serde_json::from_str(&text).expect("deserialise");
    assert_eq!(back.principal.len(), a.principal.len());
    assert_eq!(back.repetition.kind, a.repetition.kind);
    assert_eq!(serde_json::from_str::<OffsetOptions>("{}").expect("options"), OffsetOptions::default());
    let bad = OffsetOptions { tau: -1.0, ..Default::default() };
    assert!(analyze_offsets(&ex.mesh, &bad, &NoProgress).is_err());
    assert!(analyze_offsets(&TriMesh::default(), &OffsetOptions::default(), &NoProgress).is_err());
}

#[test]
fn the_offset_picture_is_written() {
    let ex = generate("shelf_sheared", 0).expect("example");
    let a = analyze(&ex.mesh);
    let path = std::env::temp_dir().join(format!("motif-offsets-test-{}.png", std::process::id()));
    motif_retarget::plot::plot_offsets(&a, "shelf_sheared", &path).expect("plot");
    let bytes = std::fs::read(&path).expect("png written");
    assert!(bytes.starts_with(b"\x89PNG"));
    // A shelf's offsets span its plane (XY), which the picture then draws alone, large (1500 ×
    // 820); a fence's lie along its length (x), drawn as one profile (1500 × 1000).
    let height = |bytes: &[u8]| u32::from_be_bytes([bytes[20], bytes[21], bytes[22], bytes[23]]);
    assert_eq!(motif_retarget::plot::line_axis(&a), None);
    assert_eq!(motif_retarget::plot::plane_axes(&a), Some((0, 1)));
    assert_eq!(height(&bytes), 820);
    // The heat scale's colour bar sits under the text, right of the plot: its palest and its
    // darkest colours are there.
    let (pale, dark) = ([255, 245, 200], [60, 10, 70]);
    assert!(has_colour(&path, [800, 400, 1500, 820], pale), "no colour bar beside the plane");
    assert!(has_colour(&path, [800, 400, 1500, 820], dark), "no colour bar beside the plane");
    let fence = analyze(&generate("fence", 0).expect("example").mesh);
    assert_eq!(motif_retarget::plot::line_axis(&fence), Some(0));
    assert_eq!(motif_retarget::plot::plane_axes(&fence), None);
    motif_retarget::plot::plot_offsets(&fence, "fence", &path).expect("plot");
    let bytes = std::fs::read(&path).expect("png written");
    assert!(bytes.starts_with(b"\x89PNG"));
    assert_eq!(height(&bytes), 1000);
    // The profile's heights are its counts: no colour bar beside the text.
    assert!(!has_colour(&path, [820, 560, 1500, 1000], dark), "a colour bar beside the profile");
    // 5% of the offsets three bins off the shelf's plane: no longer a plane, three projections.
    let mut thick = a.clone();
    let total: u32 = thick.histogram.iter().map(|b| b.count).sum();
    thick.histogram.push(motif_retarget::offsets::HistogramBin { index: [0, 0, 3], count: total / 19 });
    assert_eq!(motif_retarget::plot::plane_axes(&thick), None);
    assert_eq!(motif_retarget::plot::line_axis(&thick), None);
    motif_retarget::plot::plot_offsets(&thick, "thick", &path).expect("plot");
    assert_eq!(height(&std::fs::read(&path).expect("png written")), 1000);
    // One colour bar for the three projections, beside the text under them.
    assert!(has_colour(&path, [820, 560, 1500, 1000], dark), "no colour bar under the projections");
    let _ = std::fs::remove_file(&path);
}

/// Whether the RGB PNG at `path` has a pixel of exactly `colour` in the pixel box `[x0, y0, x1,
/// y1)`.
fn has_colour(path: &std::path::Path, [x0, y0, x1, y1]: [usize; 4], colour: [u8; 3]) -> bool {
    let mut reader = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()))
        .read_info()
        .expect("a PNG");
    let mut buf = vec![0; reader.output_buffer_size().expect("a size")];
    let info = reader.next_frame(&mut buf).expect("a frame");
    assert_eq!(info.color_type, png::ColorType::Rgb);
    let width = info.width as usize;
    (y0..y1.min(info.height as usize))
        .flat_map(|y| (x0..x1.min(width)).map(move |x| (x, y)))
        .any(|(x, y)| buf[3 * (y * width + x)..3 * (y * width + x) + 3] == colour)
}

#[test]
fn man_made_offsets_are_sparser_than_natural_ones() {
    // The thesis's observation (4.3) on two generated shapes: a shelf (man-made) and a blob.
    let o = SparsityOptions::default();
    let (_, shelf) = model_sparsity(&generate("shelf", 0).expect("shelf").mesh, &o).expect("shelf");
    let (_, blob) = model_sparsity(&blob(0.25), &o).expect("blob");
    let k = o.taus.iter().position(|&t| (t - 0.15).abs() < 1e-12).expect("τ = 0.15");
    let (s, b) = (&shelf[k], &blob[k]);
    println!("share of offsets in 7% of bins at τ = 0.15: shelf {:.3}, blob {:.3}", s.shares[0], b.shares[0]);
    assert!(s.shares[0] > b.shares[0]);
    // Curves are monotone from 0 to 1.
    for t in shelf.iter().chain(&blob) {
        assert!(t.curve.windows(2).all(|w| w[1] >= w[0] - 1e-12));
        assert!((t.curve[t.curve.len() - 1] - 1.0).abs() < 1e-9);
    }
}

// ---------------------------------------------------------------------------------------------
// Real data (shared/data): `MOTIF_DATA` or the first `shared/data` above the crate.

fn data_dir() -> Option<PathBuf> {
    motif_core::data::shared_data_dir(Path::new(env!("CARGO_MANIFEST_DIR")))
}

/// A `trans:AXIS` claim of the manifest: axis index and pitch (model units).
fn trans_claims(entry: &serde_json::Value) -> Vec<(usize, f64)> {
    let claims = entry["symmetry_check"]["claims"].as_array().cloned().unwrap_or_default();
    claims
        .iter()
        .filter_map(|c| {
            let claim = c["claim"].as_str()?;
            let axis = match claim {
                "trans:x" => 0,
                "trans:y" => 1,
                "trans:z" => 2,
                _ => return None,
            };
            Some((axis, c["pitch"].as_f64()?))
        })
        .collect()
}

/// How a principal offset meets a claim: `Some(1)` when one lies along the axis (within 10°) with
/// the claimed length (within 5%); `Some(k)` when only `k ×` one does (`k ≤ 4`: the claim is in the
/// lattice of the principal offsets but a finer period was found); `None` otherwise.
fn meets(principal: &[PrincipalOffset], axis: usize, pitch: f64) -> Option<(usize, f64)> {
    let along =
        |p: &PrincipalOffset| p.offset_model[axis].abs() >= (10f64).to_radians().cos() * p.length_model;
    for k in 1..=4 {
        if let Some(p) = principal
            .iter()
            .filter(|p| along(p))
            .find(|p| (k as f64 * p.length_model - pitch).abs() <= 0.05 * pitch)
        {
            return Some((k, p.length_model));
        }
    }
    None
}

#[test]
fn grid_models_of_the_shared_data() {
    let Some(dir) = data_dir() else {
        println!(
            "skipping: no test data at {} (set MOTIF_DATA)",
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data").display()
        );
        return;
    };
    let text = std::fs::read_to_string(dir.join("MANIFEST.json")).expect("manifest");
    let manifest: serde_json::Value = serde_json::from_str(&text).expect("manifest JSON");
    let files = manifest["files"].as_array().cloned().unwrap_or_default();
    println!(
        "{:<36} {:>7} {:>6} {:>6}  {:<14} {:>7}  principal offsets (model units: |v| along [x y z], support)",
        "model", "V", "dense", "feat", "verdict", "time s"
    );
    let mut failures = Vec::new();
    for entry in files.iter().filter(|f| f["tags"].as_array().is_some_and(|t| t.iter().any(|x| x == "grid")))
    {
        let rel = entry["path"].as_str().expect("path");
        let mesh = motif_core::io::read_mesh(&dir.join(rel)).expect("mesh loads");
        let a = analyze(&mesh);
        let principal: Vec<String> = a
            .principal
            .iter()
            .map(|p| {
                let m = p.offset_model;
                format!(
                    "{:.4} [{:.2} {:.2} {:.2}] s{}",
                    p.length_model,
                    m[0] / p.length_model,
                    m[1] / p.length_model,
                    m[2] / p.length_model,
                    p.support
                )
            })
            .collect();
        let name = rel.rsplit('/').next().unwrap_or(rel);
        println!(
            "{:<36} {:>7} {:>6} {:>6}  {:<14} {:>7.2}  {}",
            name,
            mesh.positions.len(),
            a.counts.dense,
            a.counts.features,
            format!("{:?}", a.repetition.kind),
            a.timings.total_ms / 1e3,
            principal.join("; ")
        );
        for (axis, pitch) in trans_claims(entry) {
            let axis_name = ["x", "y", "z"][axis];
            match meets(&a.principal, axis, pitch) {
                Some((1, len)) => println!(
                    "    claim trans:{axis_name}({pitch:.4}): found {len:.4} ({:+.1}%)",
                    100.0 * (len / pitch - 1.0)
                ),
                Some((k, len)) => println!(
                    "    claim trans:{axis_name}({pitch:.4}): found {len:.4}, the claim is {k} × it ({:+.1}%): a finer period",
                    100.0 * (k as f64 * len / pitch - 1.0)
                ),
                None => {
                    println!("    claim trans:{axis_name}({pitch:.4}): NOT FOUND");
                    failures.push(format!("{name} trans:{axis_name}({pitch})"));
                }
            }
        }
        if let Ok(dir) = std::env::var("MOTIF_PLOT_DIR") {
            let stem = name.split('.').next().unwrap_or(name);
            let path = Path::new(&dir).join(format!("offsets-{stem}.png"));
            motif_retarget::plot::plot_offsets(&a, name, &path).expect("plot");
        }
    }
    assert!(failures.is_empty(), "manifest claims not met: {failures:?}");
}

/// The distances kept by the matching step (thesis 4.2.2) are the L2 distances of the features'
/// descriptors, within the table's 16-bit quantisation; the matches do not change when they are
/// kept; and nothing is kept above the size limit.
#[test]
fn matching_keeps_the_pairwise_descriptor_distances() {
    use motif_retarget::offsets::{match_features, match_features_keeping_distances, prepare_features};
    let mesh = generate("fence", 0).expect("fence").mesh;
    let options = OffsetOptions::default();
    let features = prepare_features(&mesh, &options, &NoProgress).expect("features");
    let plain = match_features(&features, &[0.15], &NoProgress).expect("matches");
    let (kept, table) =
        match_features_keeping_distances(&features, &[0.15], usize::MAX, &NoProgress).expect("matches");
    assert_eq!(plain, kept);
    let table = table.expect("table");
    let valid: Vec<usize> = (0..features.len()).filter(|&i| features.valid[i]).collect();
    assert_eq!(table.len(), valid.len());
    assert!(valid.len() > 300, "{} features", valid.len());
    let l2 = |a: usize, b: usize| {
        let (x, y) = (features.descriptor(a), features.descriptor(b));
        x.iter().zip(y).map(|(p, q)| ((p - q) as f64).powi(2)).sum::<f64>().sqrt()
    };
    let mut worst: f64 = 0.0;
    for (k, &a) in valid.iter().enumerate().step_by(7) {
        for &b in valid.iter().skip(k) {
            let d = table.distance(a, b).expect("both valid");
            worst = worst.max((d - l2(a, b)).abs());
            assert_eq!(table.distance(b, a), Some(d));
        }
    }
    assert!(worst < 5e-5, "largest error {worst}");
    if let Some(bad) = (0..features.len()).find(|&i| !features.valid[i]) {
        assert_eq!(table.distance(bad, valid[0]), None);
    }
    let (_, none) =
        match_features_keeping_distances(&features, &[0.15], valid.len() - 1, &NoProgress).expect("matches");
    assert!(none.is_none());
}
