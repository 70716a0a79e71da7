//! `motif detect`: building-block detection by co-occurrence analysis (thesis chapter 5).

use motif_core::io::Model;
use motif_core::{AttributeData, PointCloud};
use motif_detect::pipeline::Method;
use motif_detect::preprocess::Epsilon;
use motif_detect::{DetectError, DetectOptions, Detection};

use crate::cli::{DetectArgs, GlobalArgs};
use crate::output::{check_outputs, maybe_json, write_json};
use crate::progress::Bar;

/// Distinct colours for classes, as `--plot` draws them; background points are grey.
const PALETTE: [[u8; 3]; 10] = motif_detect::plot::CLASS_COLOURS;

/// Checks `o` before any input is read ([`DetectOptions::validate`]); a field out of range is
/// named by its command-line flag.
pub fn validate_options(o: &DetectOptions) -> anyhow::Result<()> {
    // ε is checked here, in the user's terms: the library sees it only once multiplied by the
    // diagonal (`--epsilon=-1` was reported as "epsilon … got -33.95").
    let epsilon = match o.preprocess.epsilon {
        Epsilon::Relative(r) => Some(("--epsilon", r, "relative to the principal-axes diagonal")),
        Epsilon::Absolute(e) => Some(("--epsilon-abs", e, "in model units")),
        Epsilon::Auto => None,
    };
    if let Some((flag, v, unit)) = epsilon
        && !(v.is_finite() && v > 0.0)
    {
        return Err(crate::output::bad_input(format!("{flag} {v}: ε must be a positive number ({unit})")));
    }
    match o.validate() {
        Ok(()) => Ok(()),
        Err(DetectError::InvalidOption { name, message }) => {
            let flag = match name {
                "dictionary.words" => "--words",
                "dictionary.sigma" => "--sigma",
                "dictionary.tolerance" => "--tolerance",
                "dictionary.min_score" => "--min-score",
                "em.sigma_s" => "--sigma-s",
                "em.peak_share" => "--peak-share",
                "em.iterations" => "--em-iterations",
                "instances.bandwidth" => "--bandwidth",
                "mdl_min_saving" => "--mdl-min-saving",
                "extent.fit_trim" => "--fit-trim",
                "mdl_rounds" => "--classes",
                "mesh_samples" => "--mesh-samples",
                "preprocess.max_features" => "--max-features",
                other => other,
            };
            Err(crate::output::bad_input(format!("{flag} {message}")))
        }
        Err(e) => Err(e.into()),
    }
}

/// The options the command line asks for.
pub fn options(a: &DetectArgs, g: &GlobalArgs) -> DetectOptions {
    let mut o = DetectOptions {
        seed: g.seed,
        mdl_rounds: a.classes,
        mdl_min_saving: a.mdl_min_saving,
        mesh_samples: a.mesh_samples,
        ..Default::default()
    };
    o.preprocess.epsilon = match (a.epsilon, a.epsilon_abs) {
        (Some(r), _) => Epsilon::Relative(r),
        (None, Some(e)) => Epsilon::Absolute(e),
        (None, None) => Epsilon::Auto,
    };
    o.preprocess.kappa_threshold = a.kappa;
    o.preprocess.max_features = a.max_features;
    o.dictionary.words = a.words;
    o.dictionary.sigma = a.sigma;
    o.dictionary.tolerance = a.tolerance;
    o.dictionary.min_score = a.min_score;
    o.em.iterations = a.em_iterations;
    o.em.min_support = a.min_support;
    o.em.peak_share = a.peak_share;
    o.em.sigma_s = a.sigma_s;
    o.instances.bandwidth = a.bandwidth;
    o.method = if a.no_em { Method::Sc } else { Method::EmSc };
    o.extent.regroup = a.regroup.into();
    o.extent.repeated_segments = a.repeated_segments.into();
    o.extent.fit_boxes = !a.no_box_fit;
    o.extent.content.enabled = !a.no_content;
    o.extent.aligned.enabled = !a.no_aligned;
    o.extent.copies.enabled = !a.no_aligned && !a.no_copies;
    o.extent.shapes.enabled = !a.no_shape_split;
    o.extent.shapes.across_classes = !a.shape_split_per_class;
    o.extent.aligned.grouping = a.aligned_grouping.into();
    o.extent.aligned.mask_deep = !a.no_aligned_mask;
    o.extent.segment_support = !a.no_segment_support;
    o.extent.fit_trim = a.fit_trim;
    o
}

pub fn run(a: DetectArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    let inputs = [a.input.as_path()];
    check_outputs(
        &[
            Some(&a.output),
            a.labels.as_deref(),
            a.as_symmetry.as_deref(),
            a.plot.as_deref(),
            a.json.json.as_deref(),
        ],
        &inputs,
        g.force,
    )?;
    crate::output::check_output_formats(&[(a.plot.as_deref(), crate::output::OutputKind::Png)])?;
    if let Some(p) = &a.labels {
        if !p.extension().is_some_and(|e| e.eq_ignore_ascii_case("ply")) {
            return Err(crate::output::bad_input(format!(
                "{}: --labels is written as PLY (per-point class and instance properties); other formats \
                 cannot hold them",
                p.display()
            )));
        }
    }
    let o = options(&a, g);
    validate_options(&o)?;
    if a.mesh_samples > o.preprocess.max_points && !g.force {
        return Err(crate::output::bad_input(format!(
            "--mesh-samples {}: more than {} points (pass --force to sample that many anyway)",
            a.mesh_samples, o.preprocess.max_points
        )));
    }
    let bar = Bar::new(g.quiet);
    let model = bar.spin("reading", || super::read_model_for_geometry(&a.input))?;
    let scene = a.input.file_name().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let t = std::time::Instant::now();
    if model.is_mesh() {
        super::note(
            g,
            format!(
                "{} is a mesh: it is sampled like a scan; for exact repetition in a clean model, \
                 `motif offsets` (translations) and `motif symmetry detect` (symmetries) are faster and exact",
                a.input.display()
            ),
        );
    }
    let detection = if model.is_mesh() {
        motif_detect::detect_mesh(&model.mesh(), &scene, &o, &bar, g.force)
    } else {
        motif_detect::detect(&model.vertices, &scene, &o, &bar, g.force)
    }
    .map_err(|e| {
        // ε's limits speak of the flag the user gave, or of the automatic ε when none was given
        // (it read "invalid option `epsilon`", a name the command line does not have).
        let e = match e {
            motif_detect::DetectError::InvalidOption { name: "epsilon", message } => {
                let flag = match o.preprocess.epsilon {
                    Epsilon::Relative(_) => "--epsilon: ",
                    Epsilon::Absolute(_) => "--epsilon-abs: ",
                    Epsilon::Auto => "",
                };
                crate::output::bad_input(format!("{flag}{message}"))
            }
            e => anyhow::Error::new(e),
        };
        e.context(format!("detecting in {}", a.input.display()))
    })?;
    let seconds = t.elapsed().as_secs_f64();
    for w in &detection.report.warnings {
        super::warn(w);
    }
    write_json(&a.output, &detection.result)?;
    if let Some(p) = &a.labels {
        let cloud = detection.samples.as_ref().unwrap_or(&model.vertices);
        let labelled = labelled_cloud(cloud, &detection);
        super::write_model(p, &Model::from_point_cloud(labelled), &inputs, g, &Default::default())?;
    }
    if let Some(p) = &a.plot {
        let cloud = detection.samples.as_ref().unwrap_or(&model.vertices);
        let title = format!(
            "{}: {}, {} ({})",
            a.input.display(),
            crate::output::count(detection.result.classes.len(), "class", "classes"),
            crate::output::count(
                detection.result.classes.iter().map(|c| c.instances.len()).sum::<usize>(),
                "instance",
                "instances"
            ),
            if a.no_em { "SC, no EM" } else { "EM + SC" }
        );
        motif_detect::plot::plot_detections(
            &cloud.positions,
            &detection.labels,
            &detection.result,
            &title,
            p,
        )?;
    }
    if let Some(p) = &a.as_symmetry {
        let annotation = if model.is_mesh() {
            let (annotation, mut notes) = detection.as_symmetry_on_mesh(&model.vertices.positions);
            let annotation = keep_exact_copies(&model.mesh(), annotation, &mut notes);
            for n in notes {
                super::warn(n);
            }
            annotation
        } else {
            // A point cloud has no surface to check the copies against, as `symmetry check`
            // does for a mesh: the tolerance written is the format's default, not a measure.
            let annotation = detection.as_symmetry();
            if !detection.result.classes.is_empty() {
                super::warn(format!(
                    "{}: the instance sets are not checked against their tolerance ({:.0e} of the \
                     diagonal): {} is a point cloud, with no surface to measure the copies on; run \
                     `motif symmetry check MESH {}` on the mesh it was scanned from before deforming it",
                    p.display(),
                    annotation.tolerance,
                    a.input.display(),
                    p.display()
                ));
            }
            annotation
        };
        write_json(p, &annotation)?;
    }
    // Results print under --quiet too; only the "wrote" note is quiet.
    if !crate::output::json_on_stdout(&a.json.json) {
        let r = &detection.report;
        let per: Vec<String> = r.instances_per_class.iter().map(|n| n.to_string()).collect();
        println!(
            "{}: {} ({} {}) from {} points, ε = {}, {} features, {} in {:.2} s",
            a.input.display(),
            crate::output::count(detection.result.classes.len(), "class", "classes"),
            if per.is_empty() { "no".to_string() } else { per.join(" + ") },
            if r.instances_per_class.iter().sum::<usize>() == 1 { "instance" } else { "instances" },
            r.input_points,
            // Four decimals in model units; in exponent form when the scene is far from unit size.
            motif_core::geometry::format_length(r.epsilon, r.epsilon, 4),
            r.features,
            if a.no_em { "SC (no EM)" } else { "EM + SC" },
            seconds
        );
        println!(
            "stages (s): preprocess {:.2}  descriptors {:.2}  dictionary {:.2}  EM {:.2}  instances {:.2}  output {:.2}",
            r.seconds.preprocess,
            r.seconds.descriptors,
            r.seconds.dictionary,
            r.seconds.em,
            r.seconds.instances,
            r.seconds.output
        );
    }
    let mut written: Vec<String> = vec![a.output.display().to_string()];
    written.extend(a.labels.iter().map(|p| format!("{} (labelled points)", p.display())));
    written.extend(a.as_symmetry.iter().map(|p| format!("{} (motif_symmetry_v1)", p.display())));
    written.extend(a.plot.iter().map(|p| format!("{} (picture)", p.display())));
    maybe_json(
        &a.json.json,
        &serde_json::json!({
            "input": a.input,
            "options": o,
            "report": detection.report,
            "classes": detection.result.classes.len(),
            "seconds": seconds,
        }),
    )?;
    super::note(g, format!("wrote {}", written.join(", ")));
    Ok(())
}

/// The points with `class`/`instance` attributes (−1 for background) and class colours.
pub fn labelled_cloud(cloud: &PointCloud, d: &Detection) -> PointCloud {
    let mut out = cloud.clone();
    let class: Vec<i64> = d.labels.iter().map(|l| l.map_or(-1, |(c, _)| c as i64)).collect();
    let instance: Vec<i64> = d.labels.iter().map(|l| l.map_or(-1, |(_, i)| i as i64)).collect();
    out.colors = Some(
        d.labels
            .iter()
            .map(|l| match l {
                Some((c, i)) => {
                    let base = PALETTE[*c as usize % PALETTE.len()];
                    // Alternate instance shades so neighbouring instances are told apart.
                    let f = if i % 2 == 0 { 1.0 } else { 0.75 };
                    [(base[0] as f64 * f) as u8, (base[1] as f64 * f) as u8, (base[2] as f64 * f) as u8]
                }
                None => [190, 190, 190],
            })
            .collect(),
    );
    out.set_attribute("class", AttributeData::Int(class));
    out.set_attribute("instance", AttributeData::Int(instance));
    out
}

/// The detected classes of a mesh as an annotation `motif deform` accepts: an instance that is
/// not a copy of its class's first instance within the annotation's tolerance (measured as
/// `motif symmetry check` measures it) is left out, and so is a class left with fewer than two
/// instances, each with a note. Detection finds building blocks that differ in detail; the
/// annotation keeps the ones that are exact copies, which is what symmetry-preserving editing
/// keeps exact.
fn keep_exact_copies(
    mesh: &motif_core::TriMesh,
    annotation: motif_core::procedural::SymmetryAnnotation,
    notes: &mut Vec<String>,
) -> motif_core::procedural::SymmetryAnnotation {
    use motif_core::procedural::{Symmetry, SymmetryKind};
    let report = match motif_deform::residual::check_annotation(mesh, &annotation) {
        Ok(r) => r,
        Err(e) => {
            notes.push(format!("the symmetry annotation could not be checked against the mesh: {e}"));
            return annotation;
        }
    };
    let tol = report.tolerance;
    let mut kept =
        motif_core::procedural::SymmetryAnnotation { symmetries: Vec::new(), ..annotation.clone() };
    for (sym, check) in annotation.symmetries.into_iter().zip(&report.symmetries) {
        if check.ok {
            kept.symmetries.push(sym);
            continue;
        }
        let SymmetryKind::Instances { instances } = sym.kind else { continue };
        let n = instances.len();
        // The check lists, for each instance a ≥ 1, the maps a → 0 and 0 → a.
        let fits = |a: usize| {
            check.transforms.get(2 * (a - 1)..2 * a).is_some_and(|t| t.iter().all(|t| t.residual <= tol))
        };
        let worst = check.transforms.iter().map(|t| t.residual).fold(0.0, f64::max);
        let keep: Vec<_> =
            instances.into_iter().enumerate().filter(|&(a, _)| a == 0 || fits(a)).map(|(_, i)| i).collect();
        if keep.len() >= 2 {
            notes.push(format!(
                "{}: {} of its {n} instances {} of the first within the annotation's tolerance \
                 ({tol:.0e} of the diagonal; up to {worst:.1e}) and {} left out of the symmetry annotation",
                sym.name,
                n - keep.len(),
                if n - keep.len() == 1 { "is not a copy" } else { "are not copies" },
                if n - keep.len() == 1 { "is" } else { "are" }
            ));
            kept.symmetries
                .push(Symmetry { name: sym.name, kind: SymmetryKind::Instances { instances: keep } });
        } else {
            let why = check.problem.clone().unwrap_or_else(|| {
                format!(
                    "no instance is a copy of the first within {tol:.0e} of the diagonal (up to {worst:.1e})"
                )
            });
            notes.push(format!("{}: left out of the symmetry annotation: {why}", sym.name));
        }
    }
    kept
}
