//! Benchmark scenes with ground truth (issue 5, item 9): seeded point clouds of facades and
//! streets built from repeated parts, with the building-block ground truth in the detection schema
//! (`../shared/formats/detection.md`), at graded difficulty.
//!
//! The thesis evaluates on annotated street scans (Qmulus & TerraMobilita) and scanned objects
//! (5.5.1); these generated scenes stand in for them with the same three classes of trouble the
//! thesis names: scanning noise and holes, irregular placement, and geometric variability between
//! instances (5.1, 5.5.3).
//!
//! # Scene kinds
//! | name | what | classes (easy, default size) |
//! |---|---|---|
//! | `scene-facade` | a 20.3 × 17 m facade (7 bays of 2.9 m, 5 floors) and a 6 m ground strip | `window_a` 14, `window_b` 14, `window_c` 5, `balcony` 6, `door` 2 |
//! | `scene-street` | the facade with 4 floors, a 14 m deep street with parked cars (two rows), bins and lamp posts on the pavement | `window_a` 7, `window_b` 14, `window_c` 5, `balcony` 6, `door` 2, `lamp_post` 5, `bin` 6, `car` 8 |
//! | `scene-parts` | free-standing parts on a ground sized to fit them (one row per class when regular, scattered when irregular) | 6 of each part (`car`, `bin`, `lamp_post` when no `parts` are given) |
//!
//! Real meshes given as [`SceneOptions::parts`] become extra free-standing classes (named after
//! the file stem, 6 instances each, scaled to [`SceneOptions::part_size`]) in every kind; in
//! `scene-parts` they replace the generated street furniture.
//!
//! # Difficulty ([`Difficulty::settings`], every number a field of [`SceneSettings`])
//! | | easy | medium | hard |
//! |---|---|---|---|
//! | placement | regular grid / rows | irregular | irregular |
//! | position jitter (of the bay width; floor height × 0.4) | 0 | 0.05 | 0.12 |
//! | facade elements left out | 0 | 5% | 15% |
//! | yaw of free-standing parts | 0 | ±30° | any |
//! | Gaussian noise σ (of the element size) | 0.2% | 0.5% | 1% |
//! | non-rigid variation | 0 | 7% | 15% |
//! | scanning | every surface | 3 scanners, occlusion | 1 scanner, occlusion |
//! | clutter objects | 0 | 6 | 16 |
//! | outliers (of all points) | 0 | 0.5% | 2% |
//!
//! The *element size* is the smallest bounding-box diagonal of the scene's class templates, so
//! that the noise is relative to the finest building block (2.4 m for the facade's `window_a`, so
//! σ is 5 mm, 1.2 cm and 2.4 cm; 1.2 m for the street's and the default parts scene's `bin`).
//!
//! # Ground truth
//! One class per building block, holding the instances the scan shows: an instance of which the
//! scanners see less than [`MIN_VISIBLE_SURFACE`] (1%) of the surface is left out, as a person
//! annotating the scan could not mark it ([`SceneStats::hidden_instances`] counts them; on the
//! hard streets of seeds 1–12, 12 of the 586 instances placed, all bins). Instance `k`'s
//! `transform` is `instance_from_template`, the rigid motion (translation, yaw about y) from
//! instance 0's pose to instance `k`'s, not including the instance's own non-rigid variation.
//! `bbox_min/bbox_max` is the box of the instance's whole (varied) geometry, visible or not,
//! grown to contain its noisy points; `points` are the indices of the scene points sampled on
//! the instance. Points of the wall, the ground, clutter, outliers and hidden instances belong
//! to no instance.
//!
//! Conventions: metres; y up, x along the facade, z towards the street (the wall's front face is
//! `z = 0`). Points carry unit normals: the normal of the triangle they were sampled on, outward
//! (for user meshes without a known orientation: turned towards the scanner that sees the point).
//! Points are shuffled, so their order says nothing about the instances.

mod build;
pub use build::MIN_VISIBLE_SURFACE;
mod bvh;
mod elements;
mod layout;
mod variation;

use std::path::{Path, PathBuf};

use motif_core::{Point3, PointCloud, TriMesh};
use serde::{Deserialize, Serialize};

use crate::detection::DetectionResult;
use crate::error::{DetectError, Result};

/// The kinds of benchmark scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SceneKind {
    /// `scene-facade`: a facade with three window styles, balconies and doors.
    #[serde(rename = "scene-facade")]
    Facade,
    /// `scene-street`: a lower facade and a street with cars, bins and lamp posts.
    #[serde(rename = "scene-street")]
    Street,
    /// `scene-parts`: free-standing parts (the given meshes, else street furniture) scattered on
    /// the ground.
    #[serde(rename = "scene-parts")]
    Parts,
}

impl SceneKind {
    /// Every kind, in the order of the module documentation.
    pub const ALL: [SceneKind; 3] = [SceneKind::Facade, SceneKind::Street, SceneKind::Parts];

    /// The name the CLI uses (`motif example scene-facade ...`).
    pub fn name(self) -> &'static str {
        match self {
            SceneKind::Facade => "scene-facade",
            SceneKind::Street => "scene-street",
            SceneKind::Parts => "scene-parts",
        }
    }

    /// The kind with this [`Self::name`], if any.
    pub fn from_name(name: &str) -> Option<SceneKind> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }
}

/// The names of all scene kinds, for `motif example --list`.
pub fn scene_names() -> Vec<&'static str> {
    SceneKind::ALL.iter().map(|k| k.name()).collect()
}

/// Graded difficulty: a preset of [`SceneSettings`] (see the module documentation's table).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Difficulty {
    /// Regular placement, almost no noise, no variation, occlusion or clutter.
    Easy,
    /// Irregular placement, mild noise and variation, three scanners, some clutter. The default.
    #[default]
    Medium,
    /// Irregular placement, strong noise and variation, one scanner, clutter and outliers.
    Hard,
}

impl Difficulty {
    /// The preset's settings (the table in the module documentation).
    pub fn settings(self) -> SceneSettings {
        match self {
            Difficulty::Easy => SceneSettings {
                placement: Placement::Regular,
                jitter: 0.0,
                drop_fraction: 0.0,
                yaw_spread_deg: 0.0,
                noise: 0.002,
                variation: 0.0,
                scanning: Scanning::Complete,
                clutter_objects: 0,
                outlier_fraction: 0.0,
            },
            Difficulty::Medium => SceneSettings {
                placement: Placement::Irregular,
                jitter: 0.05,
                drop_fraction: 0.05,
                yaw_spread_deg: 30.0,
                noise: 0.005,
                variation: 0.07,
                scanning: Scanning::Scanners { count: 3 },
                clutter_objects: 6,
                outlier_fraction: 0.005,
            },
            Difficulty::Hard => SceneSettings {
                placement: Placement::Irregular,
                jitter: 0.12,
                drop_fraction: 0.15,
                yaw_spread_deg: 180.0,
                noise: 0.01,
                variation: 0.15,
                scanning: Scanning::Scanners { count: 1 },
                clutter_objects: 16,
                outlier_fraction: 0.02,
            },
        }
    }

    /// `easy`, `medium` or `hard`.
    pub fn name(self) -> &'static str {
        match self {
            Difficulty::Easy => "easy",
            Difficulty::Medium => "medium",
            Difficulty::Hard => "hard",
        }
    }
}

/// How building blocks are placed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Placement {
    /// Facade elements on the bay × floor grid, free-standing parts in evenly spaced rows, all
    /// facing the same way.
    Regular,
    /// Facade elements jittered and a random subset left out ([`SceneSettings::jitter`],
    /// [`SceneSettings::drop_fraction`]); free-standing parts at random non-overlapping positions,
    /// turned about the up axis ([`SceneSettings::yaw_spread_deg`]).
    Irregular,
}

/// Which surfaces end up in the point cloud.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Scanning {
    /// Every surface is sampled, hidden or not (a complete, hole-free acquisition).
    Complete,
    /// Only points visible from at least one of `count` virtual scanners (ray casting against
    /// every triangle of the scene) are kept. The scanners stand in a row spread evenly along x:
    /// 1.8 m high and 10 m in front of the wall for `scene-facade`, 2.2 m high (a car roof) and
    /// 9 m in front for `scene-street`, 2 m high and 6 m in front of the ground's front edge for
    /// `scene-parts`. 1 to 16.
    Scanners {
        /// Number of scanner positions, 1 to 16.
        count: usize,
    },
}

/// Every number that makes a scene easy or hard; [`Difficulty::settings`] gives the presets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneSettings {
    /// Regular or irregular placement.
    pub placement: Placement,
    /// Irregular placement: each facade element moves by up to `jitter ×` the bay width (2.9 m)
    /// horizontally (less when it would leave its bay, its largest variation included) and
    /// `jitter × 0.4 ×` the floor height (3.2 m) vertically, uniformly; balconies move with their
    /// window, doors stay on the ground. Dimensionless, 0 to 0.15.
    pub jitter: f64,
    /// Irregular placement: the fraction of facade elements (windows and their balconies; never
    /// doors) left out at random, so the grid has gaps. 0 to 0.9.
    pub drop_fraction: f64,
    /// Irregular placement: free-standing parts are turned about the up axis by a uniform angle
    /// in `[−spread, spread]` degrees (cars also face either way along the street); 180 means any
    /// direction. 0 to 180.
    pub yaw_spread_deg: f64,
    /// Standard deviation of the isotropic Gaussian noise added to every surface point, as a
    /// fraction of the element size (see the module documentation). 0 to 0.1.
    pub noise: f64,
    /// Amplitude `v` of the per-instance non-rigid variation, 0 to 0.3: each instance is scaled
    /// by `1 + v·u` independently along x, y and z (`u` uniform in [−1, 1]), bowed by up to
    /// `0.3·v` of its half-width along z (a quadratic bend across x), twisted about y by up to `v`
    /// radians over its height (free-standing parts only), and each movable part (sill, cornice,
    /// shutters, mirrors, lid, ...) is shifted by up to `0.1·v` of the template's diagonal.
    pub variation: f64,
    /// Complete sampling or virtual scanners with occlusion.
    pub scanning: Scanning,
    /// Number of clutter objects that belong to no class: random boxes (signs, air conditioners)
    /// on the wall, random boxes, spheres and poles on the ground; they occlude like everything
    /// else. 0 to 1000.
    pub clutter_objects: usize,
    /// Fraction of the points that are outliers, uniform in the scene's box enlarged by 0.5 m,
    /// with random normals. 0 to 0.5.
    pub outlier_fraction: f64,
}

impl Default for SceneSettings {
    fn default() -> Self {
        Difficulty::default().settings()
    }
}

impl SceneSettings {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<()> {
        let check = |name: &'static str, v: f64, lo: f64, hi: f64| {
            if v.is_finite() && (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err(DetectError::InvalidOption { name, message: format!("{v} is outside {lo} to {hi}") })
            }
        };
        check("jitter", self.jitter, 0.0, 0.15)?;
        check("drop_fraction", self.drop_fraction, 0.0, 0.9)?;
        check("yaw_spread_deg", self.yaw_spread_deg, 0.0, 180.0)?;
        check("noise", self.noise, 0.0, 0.1)?;
        check("variation", self.variation, 0.0, 0.3)?;
        check("outlier_fraction", self.outlier_fraction, 0.0, 0.5)?;
        if self.clutter_objects > 1000 {
            return Err(DetectError::InvalidOption {
                name: "clutter_objects",
                message: format!("{} is more than 1000", self.clutter_objects),
            });
        }
        if let Scanning::Scanners { count } = self.scanning {
            if !(1..=16).contains(&count) {
                return Err(DetectError::InvalidOption {
                    name: "scanners",
                    message: format!("{count} scanners: use 1 to 16"),
                });
            }
        }
        Ok(())
    }
}

/// Options of [`generate_scene`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SceneOptions {
    /// The difficulty preset; default medium. Ignored when [`Self::settings`] is given.
    pub difficulty: Difficulty,
    /// Explicit settings instead of the preset of [`Self::difficulty`]; default `None`.
    pub settings: Option<SceneSettings>,
    /// Number of points in the cloud (surface samples plus outliers), exactly; 1,000 to 50
    /// million, default 300,000.
    pub points: usize,
    /// Seed of every random choice (layout, variation, sampling, noise, clutter, outliers, point
    /// order); the same options give the same scene on every machine and thread count. Default 0.
    pub seed: u64,
    /// Mesh files (OBJ, PLY, OFF, STL, glTF) used as extra free-standing building blocks, one
    /// class per file; default none.
    pub parts: Vec<PathBuf>,
    /// Bounding-box diagonal each part mesh is scaled to, metres; 0.2 to 10, default 1.5.
    pub part_size: f64,
    /// Instances of each part mesh; 2 to 50, default 6.
    pub part_instances: usize,
}

impl Default for SceneOptions {
    fn default() -> Self {
        SceneOptions {
            difficulty: Difficulty::default(),
            settings: None,
            points: 300_000,
            seed: 0,
            parts: Vec::new(),
            part_size: 1.5,
            part_instances: 6,
        }
    }
}

impl SceneOptions {
    /// The settings in effect: [`Self::settings`], else the difficulty's preset.
    pub fn effective_settings(&self) -> SceneSettings {
        self.settings.clone().unwrap_or_else(|| self.difficulty.settings())
    }

    /// Checks every field's range (the settings included).
    pub fn validate(&self) -> Result<()> {
        self.effective_settings().validate()?;
        if !(1_000..=50_000_000).contains(&self.points) {
            return Err(DetectError::InvalidOption {
                name: "points",
                message: format!("{} points: use 1,000 to 50,000,000", self.points),
            });
        }
        if !(self.part_size.is_finite() && (0.2..=10.0).contains(&self.part_size)) {
            return Err(DetectError::InvalidOption {
                name: "part_size",
                message: format!("{} m: use 0.2 to 10", self.part_size),
            });
        }
        if !(2..=50).contains(&self.part_instances) {
            return Err(DetectError::InvalidOption {
                name: "part_instances",
                message: format!("{}: use 2 to 50", self.part_instances),
            });
        }
        Ok(())
    }
}

/// A mesh used as a building block: `name` becomes its class name.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenePart {
    /// Class name (for files: the file stem).
    pub name: String,
    /// The part's surface, y up, any size (it is scaled to [`SceneOptions::part_size`]).
    pub mesh: TriMesh,
}

/// Reads a part mesh; errors name the file. The class name is the file stem.
pub fn load_scene_part(path: &Path) -> Result<ScenePart> {
    let bad = |message: String| DetectError::ScenePart { path: path.to_path_buf(), message };
    let mesh = motif_core::io::read_mesh(path).map_err(|e| {
        // Core errors usually start with the file name already.
        let text = e.to_string();
        let prefix = format!("{}: ", path.display());
        bad(text.strip_prefix(&prefix).map(str::to_string).unwrap_or(text))
    })?;
    let area = mesh.area();
    if area.is_nan() || area <= 0.0 {
        return Err(bad("the mesh has no surface area to sample".into()));
    }
    // Parts are placed and scaled by their bounding box: a vertex no triangle uses widened it
    // (one stray vertex shrank the part until its instances held no points).
    let mut mesh = mesh;
    mesh.remove_unreferenced_vertices();
    let name = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "part".into());
    Ok(ScenePart { name, mesh })
}

/// What the generator did, measured while building the scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneStats {
    /// The scene kind's name.
    pub kind: String,
    /// The settings used.
    pub settings: SceneSettings,
    /// The element size, metres: the smallest bounding-box diagonal of the class templates.
    pub element_size: f64,
    /// σ of the Gaussian noise, metres (`settings.noise × element_size`).
    pub noise_sigma: f64,
    /// Scanner positions, metres (empty for complete sampling).
    pub scanners: Vec<Point3>,
    /// Fraction of the random surface samples that a scanner saw (1 for complete sampling): how
    /// much of the scene's surface area is visible.
    pub visible_fraction: f64,
    /// The same over the samples on instances only.
    pub instance_visible_fraction: f64,
    /// Points sampled on the annotated instances.
    pub instance_points: usize,
    /// Points on the wall and the ground.
    pub background_points: usize,
    /// Points on clutter objects.
    pub clutter_points: usize,
    /// Outlier points.
    pub outlier_points: usize,
    /// Clutter objects placed.
    pub clutter_objects: usize,
    /// Instances placed but left out of the ground truth because the scanners see less than
    /// [`MIN_VISIBLE_SURFACE`] of their surface (0 for complete sampling).
    #[serde(default)]
    pub hidden_instances: usize,
    /// Points sampled on those hidden instances (a few at most; they belong to no instance of
    /// the ground truth).
    #[serde(default)]
    pub hidden_points: usize,
    /// Triangles of the scene (what the scanners ray-cast against).
    pub triangles: usize,
}

/// A generated scene: the point cloud and its ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// Points with unit normals.
    pub cloud: PointCloud,
    /// Classes and instances (scene name: the kind's name; the CLI replaces it by the file name).
    pub ground_truth: DetectionResult,
    /// What was done, measured.
    pub stats: SceneStats,
}

/// Generates a benchmark scene, reading [`SceneOptions::parts`] from disk (errors name the file).
pub fn generate_scene(kind: SceneKind, options: &SceneOptions) -> Result<Scene> {
    options.validate()?;
    let parts = options.parts.iter().map(|p| load_scene_part(p)).collect::<Result<Vec<_>>>()?;
    generate_scene_with_parts(kind, options, &parts)
}

/// [`generate_scene`] with the part meshes given in memory ([`SceneOptions::parts`] is ignored).
pub fn generate_scene_with_parts(
    kind: SceneKind,
    options: &SceneOptions,
    parts: &[ScenePart],
) -> Result<Scene> {
    options.validate()?;
    let settings = options.effective_settings();
    let layout = layout::layout(kind, options, &settings, parts)?;
    build::build(kind, options, &settings, layout)
}
