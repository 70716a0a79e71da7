//! The offset-sparsity study (thesis 4.3, after He and Sun 2012): how concentrated are the offsets
//! between matched features?
//!
//! For each model: normalise, sample and describe it exactly as the offset analysis does
//! ([`prepare_features`]), match every feature for each τ in {0, 0.05, 0.1, 0.15, 0.2} (eq. 4.1,
//! one pass for all τ), bin the offsets in 0.05 cubes, sort the bins by their number of offsets and
//! accumulate: the curve gives, for a share `x` of the bins (the largest first), the share `y` of
//! the offsets they hold. The curves are averaged per category (man-made / natural) and read at
//! `x` = 7% and 20% (the thesis: at τ = 0.15, 79.9% and 97.1% for man-made models, 40.4% at 7% for
//! natural ones).
//!
//! What "bins" means: the share of the *non-empty* bins. The thesis does not say, but the other
//! reading — all bins of the offset domain, e.g. the 80³ bins of [−2, 2]³ — cannot produce its
//! numbers: a model has a few thousand offsets, so under 1% of those bins are occupied and every
//! model, natural or not, would have 100% of its offsets in 7% of the bins. With non-empty bins
//! the diagonal (a uniform spread) is the least sparse curve, as the thesis's Figure 4.5 shows.
//! Offsets are binned as matched ([`SignConvention::Raw`], as the thesis bins them); folding `v`
//! and `−v` is available for comparison. A fractional bin count is interpolated linearly.

use std::path::{Path, PathBuf};
use std::time::Instant;

use motif_core::progress::{NoProgress, Progress};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::offsets::{
    OffsetHistogram, OffsetOptions, OffsetsError, Result, SignConvention, match_features, prepare_features,
};

/// A model's category in the study (thesis 4.3: man-made and natural datasets).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Category {
    /// Architecture, furniture, vehicles, mechanical parts.
    #[serde(rename = "man-made")]
    ManMade,
    /// Humans, animals, plants.
    #[serde(rename = "natural")]
    Natural,
    /// Not known (no manifest entry, no `man-made`/`natural` parent folder).
    #[serde(rename = "unknown")]
    Unknown,
}

impl Category {
    /// The manifest / folder spelling: `man-made`, `natural`, `unknown`.
    pub fn as_str(self) -> &'static str {
        match self {
            Category::ManMade => "man-made",
            Category::Natural => "natural",
            Category::Unknown => "unknown",
        }
    }

    /// Parses the manifest / folder spelling (case-insensitive; `manmade` and `man_made` too).
    pub fn parse(s: &str) -> Option<Category> {
        match s.to_ascii_lowercase().replace('_', "-").as_str() {
            "man-made" | "manmade" => Some(Category::ManMade),
            "natural" => Some(Category::Natural),
            "unknown" => Some(Category::Unknown),
            _ => None,
        }
    }
}

/// One model of the study.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SparsityInput {
    /// The mesh file.
    pub path: PathBuf,
    /// Its category.
    pub category: Category,
}

/// Mesh file extensions the study picks up from directories.
const MESH_EXTENSIONS: &[&str] = &["obj", "ply", "off", "stl", "gltf", "glb"];

/// The inputs listed by a `MANIFEST.json` (`{"files": [{"path", "category", ...}]}`), paths
/// relative to the manifest's directory.
pub fn inputs_from_manifest(manifest: &Path) -> Result<Vec<SparsityInput>> {
    let input_err = |message: String| OffsetsError::Input { path: manifest.to_path_buf(), message };
    let text = std::fs::read_to_string(manifest).map_err(|e| input_err(e.to_string()))?;
    let json: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| input_err(format!("not JSON: {e}")))?;
    let files = json.get("files").and_then(|f| f.as_array()).ok_or_else(|| {
        input_err("no \"files\" array: expected {\"files\": [{\"path\": ..., \"category\": ...}]}".into())
    })?;
    let base = manifest.parent().unwrap_or(Path::new("."));
    files
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let path = f
                .get("path")
                .and_then(|p| p.as_str())
                .ok_or_else(|| input_err(format!("files[{i}] has no \"path\" string")))?;
            // A category the study does not know is refused: counting it silently under its
            // folder's category (or as unknown) would mix it into another average.
            let category = match f.get("category") {
                None | Some(serde_json::Value::Null) => None,
                Some(c) => Some(c.as_str().and_then(Category::parse).ok_or_else(|| {
                    input_err(format!(
                        "files[{i}] ({path}) has category {c}: the study's categories are \"man-made\" and \"natural\" (or \"unknown\")"
                    ))
                })?),
            };
            let path = base.join(path);
            let category = category.unwrap_or_else(|| category_from_path(&path));
            Ok(SparsityInput { path, category })
        })
        .collect()
}

/// The category named by the nearest parent folder called `man-made` or `natural`.
pub fn category_from_path(path: &Path) -> Category {
    path.ancestors()
        .skip(1)
        .filter_map(|a| a.file_name().and_then(|n| n.to_str()))
        .find_map(|n| Category::parse(n).filter(|c| *c != Category::Unknown))
        .unwrap_or(Category::Unknown)
}

/// The inputs named by files and directories: a `.json` file is read as a manifest, a directory
/// contributes every mesh file below it (sorted), a mesh file itself; categories come from the
/// manifest or the parent folders.
///
/// Every model is studied once: a file named twice (directly, through a directory, a manifest
/// or a symbolic link) keeps its first occurrence, and a directory reached again through a
/// symbolic link (a link to a parent makes a cycle) is not walked again. The study averages
/// models per category, so a model counted twice would weigh twice. [`collect_inputs_noting`]
/// also returns the repeats that were dropped.
pub fn collect_inputs(paths: &[PathBuf]) -> Result<Vec<SparsityInput>> {
    Ok(collect_inputs_noting(paths)?.0)
}

/// [`collect_inputs`], with the paths dropped as repeats of an earlier input.
pub fn collect_inputs_noting(paths: &[PathBuf]) -> Result<(Vec<SparsityInput>, Vec<PathBuf>)> {
    let mut out = Vec::new();
    let mut visited_dirs = std::collections::HashSet::new();
    for p in paths {
        if p.is_dir() {
            let mut files = Vec::new();
            walk(p, &mut files, &mut visited_dirs)?;
            files.sort();
            out.extend(files.into_iter().map(|path| {
                let category = category_from_path(&path);
                SparsityInput { path, category }
            }));
        } else if p.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("json")) {
            out.extend(inputs_from_manifest(p)?);
        } else if p.is_file() {
            out.push(SparsityInput { path: p.clone(), category: category_from_path(p) });
        } else {
            return Err(OffsetsError::Input { path: p.clone(), message: "no such file or directory".into() });
        }
    }
    let mut seen = std::collections::HashSet::new();
    let mut repeats = Vec::new();
    out.retain(|input| {
        // A path that cannot be resolved (a manifest entry that does not exist) is kept: the
        // study reports it as skipped with the reason.
        let key = std::fs::canonicalize(&input.path).unwrap_or_else(|_| input.path.clone());
        let first = seen.insert(key);
        if !first {
            repeats.push(input.path.clone());
        }
        first
    });
    Ok((out, repeats))
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>, visited: &mut std::collections::HashSet<PathBuf>) -> Result<()> {
    let canonical = std::fs::canonicalize(dir)
        .map_err(|e| OffsetsError::Input { path: dir.to_path_buf(), message: e.to_string() })?;
    if !visited.insert(canonical) {
        return Ok(());
    }
    let entries = std::fs::read_dir(dir)
        .map_err(|e| OffsetsError::Input { path: dir.to_path_buf(), message: e.to_string() })?;
    for e in entries {
        let path =
            e.map_err(|e| OffsetsError::Input { path: dir.to_path_buf(), message: e.to_string() })?.path();
        if path.is_dir() {
            walk(&path, out, visited)?;
        } else if path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| MESH_EXTENSIONS.iter().any(|m| e.eq_ignore_ascii_case(m)))
        {
            out.push(path);
        }
    }
    Ok(())
}

/// Options of the sparsity study.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SparsityOptions {
    /// Sampling, SHOT and binning parameters (thesis 4.3: spacings 0.02 / 0.06, radius 0.2, bins
    /// 0.05); its `tau` is ignored in favour of `taus`. Default [`OffsetOptions::default`].
    pub offsets: OffsetOptions,
    /// The minimum offset lengths τ compared (thesis Fig. 4.5), normalised units; default
    /// `[0, 0.05, 0.1, 0.15, 0.2]`.
    pub taus: Vec<f64>,
    /// How `v` and `−v` are binned; default [`SignConvention::Raw`] (as the thesis).
    pub sign: SignConvention,
    /// Bin shares at which the curves are read (thesis 4.3: 7% and 20%); default `[0.07, 0.2]`.
    pub read_at: Vec<f64>,
    /// Points of each sampled cumulative curve, evenly spaced over [0, 1] of the bins; default
    /// 101.
    pub curve_points: usize,
}

impl Default for SparsityOptions {
    fn default() -> Self {
        SparsityOptions {
            offsets: OffsetOptions::default(),
            taus: vec![0.0, 0.05, 0.1, 0.15, 0.2],
            sign: SignConvention::Raw,
            read_at: vec![0.07, 0.2],
            curve_points: 101,
        }
    }
}

/// One model at one τ.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TauSparsity {
    /// The threshold τ.
    pub tau: f64,
    /// Matched offsets.
    pub offsets: usize,
    /// Non-empty bins.
    pub bins: usize,
    /// Share of offsets in the largest `read_at[i]` share of the bins.
    pub shares: Vec<f64>,
    /// The cumulative curve at `curve_points` evenly spaced bin shares.
    pub curve: Vec<f64>,
}

/// One model's result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelSparsity {
    /// The mesh file.
    pub path: PathBuf,
    /// Its category.
    pub category: Category,
    /// Mesh vertices.
    pub vertices: usize,
    /// Features with a descriptor.
    pub features: usize,
    /// Per τ, in the order of [`SparsityOptions::taus`]; empty when the model failed.
    pub per_tau: Vec<TauSparsity>,
    /// Seconds spent on this model.
    pub seconds: f64,
    /// Why the model was left out, if it was (unreadable file, no surface, ...).
    pub error: Option<String>,
}

/// The average over one category at one τ.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CategoryTau {
    /// The threshold τ.
    pub tau: f64,
    /// Mean share of offsets at each `read_at` bin share.
    pub shares: Vec<f64>,
    /// Smallest and largest per-model share at each `read_at`.
    pub share_range: Vec<[f64; 2]>,
    /// The mean cumulative curve.
    pub curve: Vec<f64>,
}

/// The averages of one category.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CategorySparsity {
    /// The category.
    pub category: Category,
    /// Models averaged (those without error).
    pub models: usize,
    /// Per τ.
    pub per_tau: Vec<CategoryTau>,
}

/// A number the thesis reports, for comparison.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ThesisReference {
    /// The category.
    pub category: Category,
    /// The threshold τ.
    pub tau: f64,
    /// The bin share.
    pub bins: f64,
    /// The share of offsets the thesis measured.
    pub offsets: f64,
}

/// The thesis's numbers (4.3): at τ = 0.15, man-made 79.9% in 7% and 97.1% in 20% of the bins;
/// natural 40.4% in 7%.
pub fn thesis_reference() -> Vec<ThesisReference> {
    vec![
        ThesisReference { category: Category::ManMade, tau: 0.15, bins: 0.07, offsets: 0.799 },
        ThesisReference { category: Category::ManMade, tau: 0.15, bins: 0.20, offsets: 0.971 },
        ThesisReference { category: Category::Natural, tau: 0.15, bins: 0.07, offsets: 0.404 },
    ]
}

/// The study's result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SparsityReport {
    /// Per model, in input order.
    pub models: Vec<ModelSparsity>,
    /// Per category (man-made, natural, unknown; only those present).
    pub categories: Vec<CategorySparsity>,
    /// The thesis's numbers.
    pub thesis: Vec<ThesisReference>,
    /// The options used.
    pub options: SparsityOptions,
    /// Wall-clock seconds of the whole study.
    pub seconds: f64,
}

/// Share of the total in the largest `x` share of the bins (`counts` sorted descending),
/// interpolating linearly within a bin.
pub fn cumulative_share(counts: &[u32], total: usize, x: f64) -> f64 {
    if counts.is_empty() || total == 0 {
        return 0.0;
    }
    let pos = x.clamp(0.0, 1.0) * counts.len() as f64;
    let whole = pos.floor() as usize;
    let mut sum: f64 = counts[..whole.min(counts.len())].iter().map(|&c| c as f64).sum();
    if whole < counts.len() {
        sum += (pos - whole as f64) * counts[whole] as f64;
    }
    sum / total as f64
}

fn check(options: &SparsityOptions) -> Result<()> {
    options.offsets.validate()?;
    if options.taus.is_empty() || options.taus.iter().any(|t| !(t.is_finite() && *t >= 0.0)) {
        return Err(OffsetsError::InvalidOption {
            name: "taus",
            message: format!("need at least one finite τ ≥ 0, got {:?}", options.taus),
        });
    }
    if options.curve_points < 2 {
        return Err(OffsetsError::InvalidOption {
            name: "curve_points",
            message: format!("need at least 2, got {}", options.curve_points),
        });
    }
    if options.read_at.iter().any(|x| !(0.0..=1.0).contains(x)) {
        return Err(OffsetsError::InvalidOption {
            name: "read_at",
            message: format!("bin shares must be in [0, 1], got {:?}", options.read_at),
        });
    }
    Ok(())
}

/// Sparsity of one mesh (see the module docs).
pub fn model_sparsity(
    mesh: &motif_core::mesh::TriMesh,
    options: &SparsityOptions,
) -> Result<(usize, Vec<TauSparsity>)> {
    check(options)?;
    let features = prepare_features(mesh, &options.offsets, &NoProgress)?;
    let matches = match_features(&features, &options.taus, &NoProgress)?;
    let per_tau = options
        .taus
        .iter()
        .zip(matches)
        .map(|(&tau, m)| {
            let h = OffsetHistogram::from_offsets(
                m.iter().map(|m| m.offset),
                options.offsets.bin_size,
                options.sign,
            );
            let counts = h.sorted_counts();
            let total = h.total();
            let n = options.curve_points;
            TauSparsity {
                tau,
                offsets: total,
                bins: counts.len(),
                shares: options.read_at.iter().map(|&x| cumulative_share(&counts, total, x)).collect(),
                curve: (0..n).map(|i| cumulative_share(&counts, total, i as f64 / (n - 1) as f64)).collect(),
            }
        })
        .collect();
    Ok((features.num_valid(), per_tau))
}

/// Runs the study over `inputs` in parallel (one progress unit per model). A model that cannot be
/// read or analysed is reported with its error and left out of the averages.
pub fn sparsity_study(
    inputs: &[SparsityInput],
    options: &SparsityOptions,
    progress: &dyn Progress,
) -> Result<SparsityReport> {
    check(options)?;
    let t0 = Instant::now();
    progress.start("sparsity study", inputs.len() as u64);
    let models: Vec<ModelSparsity> = inputs
        .par_iter()
        .map(|input| {
            let t = Instant::now();
            let mut m = ModelSparsity {
                path: input.path.clone(),
                category: input.category,
                vertices: 0,
                features: 0,
                per_tau: Vec::new(),
                seconds: 0.0,
                error: None,
            };
            let result =
                motif_core::io::read_mesh(&input.path).map_err(OffsetsError::from).and_then(|mesh| {
                    m.vertices = mesh.positions.len();
                    model_sparsity(&mesh, options)
                });
            match result {
                Ok((features, per_tau)) => {
                    m.features = features;
                    m.per_tau = per_tau;
                }
                Err(e) => m.error = Some(e.to_string()),
            }
            m.seconds = t.elapsed().as_secs_f64();
            progress.inc(1);
            m
        })
        .collect();
    progress.finish();

    let mut cats: Vec<Category> = models.iter().filter(|m| m.error.is_none()).map(|m| m.category).collect();
    cats.sort();
    cats.dedup();
    let categories = cats
        .into_iter()
        .map(|category| {
            let ms: Vec<&ModelSparsity> =
                models.iter().filter(|m| m.error.is_none() && m.category == category).collect();
            let n = ms.len() as f64;
            let per_tau = options
                .taus
                .iter()
                .enumerate()
                .map(|(k, &tau)| {
                    let shares = (0..options.read_at.len())
                        .map(|r| ms.iter().map(|m| m.per_tau[k].shares[r]).sum::<f64>() / n)
                        .collect();
                    let share_range = (0..options.read_at.len())
                        .map(|r| {
                            let v = ms.iter().map(|m| m.per_tau[k].shares[r]);
                            [v.clone().fold(f64::INFINITY, f64::min), v.fold(f64::NEG_INFINITY, f64::max)]
                        })
                        .collect();
                    let curve = (0..options.curve_points)
                        .map(|i| ms.iter().map(|m| m.per_tau[k].curve[i]).sum::<f64>() / n)
                        .collect();
                    CategoryTau { tau, shares, share_range, curve }
                })
                .collect();
            CategorySparsity { category, models: ms.len(), per_tau }
        })
        .collect();
    Ok(SparsityReport {
        models,
        categories,
        thesis: thesis_reference(),
        options: options.clone(),
        seconds: t0.elapsed().as_secs_f64(),
    })
}

impl SparsityReport {
    /// A plain-text table: per category and τ the mean share of offsets at each `read_at`, with
    /// the thesis's numbers where it gives them.
    pub fn table(&self) -> String {
        let mut s = String::from("category  models  tau   ");
        for x in &self.options.read_at {
            s += &format!(" offsets@{:>3.0}%bins", 100.0 * x);
        }
        s += "   thesis\n";
        for c in &self.categories {
            for t in &c.per_tau {
                s += &format!("{:<9} {:>6}  {:<5.2}", c.category.as_str(), c.models, t.tau);
                for v in &t.shares {
                    s += &format!(" {:>16.1}%", 100.0 * v);
                }
                let refs: Vec<String> = self
                    .thesis
                    .iter()
                    .filter(|r| r.category == c.category && (r.tau - t.tau).abs() < 1e-9)
                    .map(|r| format!("{:.1}%@{:.0}%", 100.0 * r.offsets, 100.0 * r.bins))
                    .collect();
                s += &format!("   {}\n", refs.join(", "));
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cumulative_share_interpolates() {
        let c = [6, 2, 1, 1];
        assert_eq!(cumulative_share(&c, 10, 0.0), 0.0);
        assert!((cumulative_share(&c, 10, 0.25) - 0.6).abs() < 1e-12);
        assert!((cumulative_share(&c, 10, 0.375) - 0.7).abs() < 1e-12);
        assert!((cumulative_share(&c, 10, 1.0) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn categories_from_folders() {
        assert_eq!(category_from_path(Path::new("/d/man-made/a.stl")), Category::ManMade);
        assert_eq!(category_from_path(Path::new("/d/natural/x/b.off")), Category::Natural);
        assert_eq!(category_from_path(Path::new("/d/other/c.off")), Category::Unknown);
        assert_eq!(Category::parse("Man_Made"), Some(Category::ManMade));
    }

    #[test]
    fn a_manifest_category_the_study_does_not_know_is_refused_by_entry() {
        let dir = tempfile::tempdir().expect("temp dir");
        let m = dir.path().join("MANIFEST.json");
        let write = |cat: &str| {
            std::fs::write(&m, format!(r#"{{"files": [{{"path": "man-made/a.off"{cat}}}]}}"#)).expect("write")
        };
        write(r#", "category": "furniture""#);
        let e = inputs_from_manifest(&m).expect_err("furniture is no category of the study").to_string();
        assert!(e.contains("files[0]") && e.contains("furniture"), "{e}");
        write(r#", "category": "Natural""#);
        assert_eq!(inputs_from_manifest(&m).expect("natural")[0].category, Category::Natural);
        write("");
        assert_eq!(inputs_from_manifest(&m).expect("from the folder")[0].category, Category::ManMade);
    }

    #[test]
    fn every_model_is_collected_once_through_repeats_and_link_cycles() {
        let dir = tempfile::tempdir().expect("temp dir");
        let made = dir.path().join("man-made");
        std::fs::create_dir(&made).expect("mkdir");
        let a = made.join("a.off");
        std::fs::write(&a, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").expect("write");
        std::fs::write(made.join("b.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").expect("write");
        std::fs::write(made.join("notes.txt"), "not a mesh").expect("write");
        #[cfg(unix)]
        std::os::unix::fs::symlink("..", made.join("up")).expect("symlink to the parent: a cycle");
        let (inputs, repeats) =
            collect_inputs_noting(&[dir.path().to_path_buf(), a.clone(), made.join(".").join("a.off")])
                .expect("collect");
        let names: Vec<_> = inputs.iter().map(|i| i.path.file_name().unwrap().to_owned()).collect();
        assert_eq!(names, ["a.off", "b.obj"], "{inputs:?}");
        assert!(inputs.iter().all(|i| i.category == Category::ManMade));
        assert_eq!(repeats.len(), 2, "the two direct repeats of a.off: {repeats:?}");
    }
}
