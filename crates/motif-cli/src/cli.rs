//! Command-line syntax (clap derive). Each subcommand's arguments live next to its doc string so
//! `motif help CMD` is the reference.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

/// Neighbours of a point-cloud normal fit (`motif normals -k`) by default.
pub const NORMALS_K: usize = 16;

/// Structure-aware 3D content creation: find symmetries, repeated building blocks and dominant
/// offsets in meshes and scans, and use them to deform and resize models.
#[derive(Debug, Parser)]
#[command(name = "motif", version, propagate_version = true, arg_required_else_help = true)]
pub struct Cli {
    #[command(flatten)]
    pub global: GlobalArgs,
    #[command(subcommand)]
    pub command: Command,
}

/// Options every subcommand accepts.
#[derive(Debug, Args)]
pub struct GlobalArgs {
    /// Hide progress bars and informational messages (results, warnings and errors still print).
    #[arg(long, short, global = true)]
    pub quiet: bool,
    /// Seed for every random choice, so results reproduce exactly.
    #[arg(long, global = true, default_value_t = 1)]
    pub seed: u64,
    /// Allow an output to overwrite an input file, and lift the size limits (of detect, retarget,
    /// sample). Existing files that are not inputs are replaced without it, as `cp` does.
    #[arg(long, global = true)]
    pub force: bool,
    /// Number of worker threads (default: all cores).
    #[arg(long, global = true)]
    pub threads: Option<usize>,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Print counts, bounding box, components and edge statistics of a mesh or point cloud.
    Info(InfoArgs),
    /// Convert between formats (OBJ, PLY, OFF, STL, glTF/GLB), chosen by extension.
    Convert(ConvertArgs),
    /// Sample points on a surface (random, or Poisson-disc) or resample a point cloud.
    Sample(SampleArgs),
    /// Estimate oriented normals (PCA + consistent orientation) and write them with the points (PLY, OBJ, OFF, glTF).
    Normals(NormalsArgs),
    /// Principal curvatures and directions by quadratic (jet) fitting.
    Curvature(CurvatureArgs),
    /// Local shape descriptors.
    #[command(subcommand)]
    Features(FeaturesCommand),
    /// Rigidly align one shape to another with ICP.
    Align(AlignArgs),
    /// Drag handles; every annotated symmetry stays exact (thesis chapter 3).
    Deform(DeformArgs),
    /// Benchmarks that print tables comparable with the thesis's.
    #[command(subcommand)]
    Bench(BenchCommand),
    /// Symmetries: detect them automatically, or check an annotation against a mesh.
    #[command(subcommand)]
    Symmetry(SymmetryCommand),
    /// Resize a model along its own repetitive structure (thesis 4.2.2): offsets, MRF, graph cut.
    Retarget(RetargetArgs),
    /// Dominant and principal translational offsets of a model (thesis 4.2.1, 4.4).
    Offsets(OffsetsArgs),
    /// The offset-sparsity study (thesis 4.3): how concentrated offsets are, per category.
    Sparsity(SparsityArgs),
    /// Find repeated building blocks in a scan or mesh by co-occurrence analysis (thesis chapter 5).
    Detect(DetectArgs),
    /// Score building-block detections against ground truth (thesis 5.5.2): precision, recall, F,
    /// the PR curve and the stress curve; averaged over scenes when given several pairs.
    Eval(EvalArgs),
    /// Multi-label MRF problems (alpha-expansion on Boykov–Kolmogorov max-flow).
    #[command(subcommand)]
    Mrf(MrfCommand),
    /// Baseline detectors to compare building-block detection with (thesis 5.5.3).
    #[command(subcommand)]
    Baseline(BaselineCommand),
    /// Write a procedural example shape with known structure, or a benchmark scene (scene-*).
    Example(ExampleArgs),
    /// Run everything Motif can do, end to end, on generated examples, and say what happened.
    Demo(DemoArgs),
    /// A local web app: open a model, see its symmetries and detections, deform it with the mouse,
    /// resize it along its repetitions, export. Prints the URL to open.
    Studio(StudioArgs),
}

#[derive(Debug, Args)]
pub struct StudioArgs {
    /// A model under --root that every new page opens first (a path from the current folder,
    /// or from the root).
    pub model: Option<PathBuf>,
    /// TCP port (0: a free port chosen by the system).
    #[arg(long, default_value_t = 0)]
    pub port: u16,
    /// The only folder the studio reads and writes files in ("." is the current directory).
    #[arg(long, default_value = ".")]
    pub root: PathBuf,
    /// Address to listen on. The default 127.0.0.1 keeps the studio on this machine; any other
    /// address lets the network read and write files under --root.
    #[arg(long, default_value = "127.0.0.1")]
    pub host: std::net::IpAddr,
}

/// Where a JSON report goes: `--json` alone prints it on stdout, `--json FILE` writes a file.
#[derive(Debug, Args, Clone, Default)]
pub struct JsonArg {
    /// Write a machine-readable JSON report (to FILE, or stdout when no FILE is given).
    #[arg(long, value_name = "FILE", num_args = 0..=1, default_missing_value = "-", value_parser = json_report_path)]
    pub json: Option<PathBuf>,
}

/// A path for a `--json` report: not a model or picture file (as [`json_path`]). Once the
/// arguments are parsed, [`json_report_clash`] also refuses an existing file that holds one of
/// the documents Motif reads: `motif eval --json r.json g.json r2.json` took the result `r.json`
/// as the report's file and overwrote it. `--json` takes an optional value, so the messages say
/// how it can take an input by mistake.
pub fn json_report_path(value: &str) -> Result<PathBuf, String> {
    if let Some(e) = model_extension(value) {
        return Err(format!(
            "a JSON report would be written to {value}, whose .{e} extension names a model or picture \
             format ({JSON_REPORT_HINT})"
        ));
    }
    Ok(PathBuf::from(value))
}

const JSON_REPORT_HINT: &str =
    "did --json take an input file as its value? put --json after the inputs, or write --json=REPORT.json";

/// Why a `--json` report may not replace the file at `path`, when it holds one of Motif's input
/// documents (an annotation, handles, an MRF problem, a detection result or ground truth, a
/// data-set manifest): `--json` given before the inputs takes the first of them as its value.
/// Checked once the arguments are parsed, and not under `--force`, which lets any output
/// replace an input (a value parser sees no other flag: this check used to look for `--force`
/// among the raw arguments). Only a regular file is looked into: reading a pipe, a FIFO or a
/// terminal given as the report's path (`--json /dev/stdout | cat`) waited forever for input.
pub fn json_report_clash(path: &std::path::Path) -> Option<String> {
    let mut head = Vec::new();
    if std::fs::metadata(path).is_ok_and(|m| m.is_file())
        && let Ok(f) = std::fs::File::open(path)
    {
        use std::io::Read;
        let _ = f.take(1 << 16).read_to_end(&mut head);
    }
    let text = String::from_utf8_lossy(&head);
    // The documents' first keys: reports start with neither.
    let first_key =
        |key: &str| text.trim_start().strip_prefix('{').is_some_and(|t| t.trim_start().starts_with(key));
    let kind = if first_key("\"format\"")
        && ["motif_symmetry_v1", "motif_handles_v1", "mrf_grid_v1"].iter().any(|f| text.contains(f))
    {
        "an annotation, handles or MRF problem"
    } else if first_key("\"scene\"") && text.contains("\"classes\"") {
        "a detection result or ground truth"
    } else if is_manifest(&text) {
        "a data-set manifest (a list of files, as `motif sparsity` reads)"
    } else {
        return None;
    };
    Some(format!(
        "{} holds {kind}, which a report would overwrite ({JSON_REPORT_HINT}; or pass --force)",
        path.display()
    ))
}

/// Whether JSON text (possibly cut) is a data-set manifest, `{"files": [{"path": ...}, ...]}`
/// as `../shared/data/MANIFEST.json`: a top-level `"files"` key whose value opens a list of
/// objects with a `"path"`.
fn is_manifest(text: &str) -> bool {
    let Some(at) = text.find("\"files\"") else { return false };
    let rest = text[at + "\"files\"".len()..].trim_start();
    let opens_list_of_objects = rest
        .strip_prefix(':')
        .map(str::trim_start)
        .and_then(|r| r.strip_prefix('['))
        .is_some_and(|r| r.trim_start().starts_with('{'));
    text.trim_start().starts_with('{') && opens_list_of_objects && rest.contains("\"path\"")
}

/// A path a JSON document (a result, an annotation) is written to with `-o`: refused when its
/// extension names a model or picture format, since `motif detect x.ply -o r.ply` wrote JSON
/// into a `.ply`.
pub fn json_path(value: &str) -> Result<PathBuf, String> {
    match model_extension(value) {
        Some(e) => Err(format!(
            "this output is a JSON document, but {value}'s .{e} extension names a model or picture \
             format (name it .json)"
        )),
        None => Ok(PathBuf::from(value)),
    }
}

/// Value parser for one of `--steps`: a whole number of cells, said so when it is not one (Rust's
/// own message was "invalid digit found in string").
pub fn step_count(value: &str) -> Result<i32, String> {
    match value.trim().parse::<i32>() {
        Ok(v) => Ok(v),
        // Digits that overflow are a number, only far too large.
        Err(_)
            if {
                let digits = value.trim().trim_start_matches(['-', '+']);
                !digits.is_empty() && digits.chars().all(|c| c.is_ascii_digit())
            } =>
        {
            Err("far more cells than a resize can take (the retargeting grid is limited to 10⁶ voxels)"
                .to_string())
        }
        Err(_) => {
            Err("not a whole number of cells (steps are integers such as 2,1,0; negative shrinks)"
                .to_string())
        }
    }
}

/// The extension of `value`, lower case, when it names a model or picture format.
pub fn model_extension(value: &str) -> Option<String> {
    let ext =
        std::path::Path::new(value).extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase)?;
    ["obj", "ply", "off", "stl", "gltf", "glb", "png", "jpg", "jpeg", "svg"]
        .contains(&ext.as_str())
        .then_some(ext)
}

/// Value parser for one file of a comma-separated list: an empty name (a stray comma, as in
/// `--parts a.obj,`) is named as such, where clap's own parser would say that no value was given.
pub fn listed_path(value: &str) -> Result<PathBuf, String> {
    if value.is_empty() {
        Err("empty file name in the comma-separated list (a stray comma?)".to_string())
    } else {
        Ok(PathBuf::from(value))
    }
}

#[derive(Debug, Args)]
pub struct InfoArgs {
    /// Input mesh or point cloud.
    pub input: PathBuf,
    #[command(flatten)]
    pub json: JsonArg,
}

#[derive(Debug, Clone, Copy, ValueEnum, Default)]
pub enum PlyEncodingArg {
    Ascii,
    #[default]
    BinaryLe,
    BinaryBe,
}

/// The extent stage of `motif detect` (motif_detect::extent).
#[derive(Debug, Clone, Copy, ValueEnum, Default, PartialEq)]
pub enum RegroupArg {
    /// The co-occurrence stages' boxes and classes, as in the thesis.
    None,
    /// Boxes grown to their segment off the wall and ground planes, repeated instances removed,
    /// classes split and merged by size.
    #[default]
    Extent,
}

impl From<RegroupArg> for motif_detect::extent::Regroup {
    fn from(a: RegroupArg) -> Self {
        match a {
            RegroupArg::None => motif_detect::extent::Regroup::None,
            RegroupArg::Extent => motif_detect::extent::Regroup::Extent,
        }
    }
}

/// How the extent stage's last step groups instances (motif_detect::aligned::Grouping).
#[derive(Debug, Clone, Copy, ValueEnum, Default, PartialEq)]
pub enum AlignedGroupingArg {
    /// Communities of the graph of all instances weighted by image distance.
    #[default]
    Communities,
    /// Each instance moves to the class whose members it resembles most.
    Reassign,
}

impl From<AlignedGroupingArg> for motif_detect::aligned::Grouping {
    fn from(a: AlignedGroupingArg) -> Self {
        match a {
            AlignedGroupingArg::Communities => motif_detect::aligned::Grouping::Communities,
            AlignedGroupingArg::Reassign => motif_detect::aligned::Grouping::Reassign,
        }
    }
}

/// A step of `motif detect`'s extent stage (motif_detect::segment_classes).
#[derive(Debug, Clone, Copy, ValueEnum, Default, PartialEq)]
pub enum RepeatedSegmentsArg {
    /// Only the co-occurrence classes.
    None,
    /// Segments no class explains, repeated by size, become classes.
    Sizes,
    /// As `sizes`, then segments longer than 64ε that no group took are grouped by shape.
    #[default]
    Classes,
}

impl From<RepeatedSegmentsArg> for motif_detect::segment_classes::RepeatedSegments {
    fn from(a: RepeatedSegmentsArg) -> Self {
        match a {
            RepeatedSegmentsArg::None => motif_detect::segment_classes::RepeatedSegments::None,
            RepeatedSegmentsArg::Sizes => motif_detect::segment_classes::RepeatedSegments::Sizes,
            RepeatedSegmentsArg::Classes => motif_detect::segment_classes::RepeatedSegments::Classes,
        }
    }
}

#[derive(Debug, Clone, Copy, ValueEnum, Default)]
pub enum StlEncodingArg {
    #[default]
    Binary,
    Ascii,
}

#[derive(Debug, Args, Default)]
pub struct EncodingArgs {
    /// PLY encoding of the output [default: binary-le]
    #[arg(long, value_enum)]
    pub ply_encoding: Option<PlyEncodingArg>,
    /// STL encoding of the output [default: binary]
    #[arg(long, value_enum)]
    pub stl_encoding: Option<StlEncodingArg>,
}

#[derive(Debug, Args)]
pub struct ConvertArgs {
    /// Input file.
    pub input: PathBuf,
    /// Output file; its extension picks the format. Also `-o OUTPUT`.
    #[arg(required_unless_present = "output_flag")]
    pub output: Option<PathBuf>,
    /// The output, given as an option instead (as the pipeline commands take it).
    #[arg(short = 'o', long = "output", value_name = "OUTPUT", conflicts_with = "output")]
    pub output_flag: Option<PathBuf>,
    #[command(flatten)]
    pub encoding: EncodingArgs,
    #[command(flatten)]
    pub json: JsonArg,
}

#[derive(Debug, Args)]
#[command(group(clap::ArgGroup::new("amount").required(true).args(["radius", "count"])))]
pub struct SampleArgs {
    /// Input mesh or point cloud.
    pub input: PathBuf,
    /// Output point cloud (PLY keeps normals). Also `-o OUTPUT`.
    #[arg(required_unless_present = "output_flag")]
    pub output: Option<PathBuf>,
    /// The output, given as an option instead (as the pipeline commands take it).
    #[arg(short = 'o', long = "output", value_name = "OUTPUT", conflicts_with = "output")]
    pub output_flag: Option<PathBuf>,
    /// Poisson-disc radius in model units (no two samples closer; implies --poisson).
    #[arg(long)]
    pub radius: Option<f64>,
    /// Number of samples (exact for random sampling, approximate for Poisson-disc).
    #[arg(long)]
    pub count: Option<usize>,
    /// Poisson-disc sampling (blue noise) instead of independent area-weighted samples.
    #[arg(long)]
    pub poisson: bool,
    #[command(flatten)]
    pub encoding: EncodingArgs,
    #[command(flatten)]
    pub json: JsonArg,
}

#[derive(Debug, Clone, Copy, ValueEnum, Default, PartialEq)]
pub enum OrientationArg {
    /// Consistent over a neighbour graph, outward on closed shapes.
    #[default]
    Consistent,
    /// Towards the point given by --viewpoint.
    Viewpoint,
    /// Unoriented PCA normals (sign arbitrary).
    None,
}

#[derive(Debug, Args)]
pub struct NormalsArgs {
    /// Input point cloud or mesh.
    pub input: PathBuf,
    /// Output with the normals (PLY, OBJ, OFF, glTF/GLB; STL holds no point normals). Also `-o OUTPUT`.
    #[arg(required_unless_present = "output_flag")]
    pub output: Option<PathBuf>,
    /// The output, given as an option instead (as the pipeline commands take it).
    #[arg(short = 'o', long = "output", value_name = "OUTPUT", conflicts_with = "output")]
    pub output_flag: Option<PathBuf>,
    /// Neighbours used by the PCA fit.
    #[arg(short, long, default_value_t = NORMALS_K)]
    pub k: usize,
    /// How signs are chosen.
    #[arg(long, value_enum, default_value_t)]
    pub orientation: OrientationArg,
    /// Viewpoint for --orientation viewpoint, as X,Y,Z.
    #[arg(long, value_delimiter = ',')]
    pub viewpoint: Option<Vec<f64>>,
    /// For meshes: estimate from the vertices as if they were a point cloud, instead of using
    /// area-weighted face normals.
    #[arg(long)]
    pub from_points: bool,
    #[command(flatten)]
    pub encoding: EncodingArgs,
    #[command(flatten)]
    pub json: JsonArg,
}

#[derive(Debug, Args)]
pub struct CurvatureArgs {
    /// Input mesh or point cloud (normals used when present).
    pub input: PathBuf,
    /// Output: PLY (properties k1 k2 d1x d1y d1z d2x d2y d2z) or CSV. Also `-o OUTPUT`.
    #[arg(required_unless_present = "output_flag")]
    pub output: Option<PathBuf>,
    /// The output, given as an option instead (as the pipeline commands take it).
    #[arg(short = 'o', long = "output", value_name = "OUTPUT", conflicts_with = "output")]
    pub output_flag: Option<PathBuf>,
    /// Neighbours of the quadratic fit (default 15).
    #[arg(short, long, conflicts_with = "radius")]
    pub k: Option<usize>,
    /// Neighbourhood radius in model units instead of k nearest.
    #[arg(long)]
    pub radius: Option<f64>,
    #[command(flatten)]
    pub encoding: EncodingArgs,
    #[command(flatten)]
    pub json: JsonArg,
}

#[derive(Debug, Subcommand)]
pub enum FeaturesCommand {
    /// SHOT descriptors (Tombari et al. 2010): 352 values per keypoint, PCL-compatible.
    Shot(ShotArgs),
}

#[derive(Debug, Clone, Copy, ValueEnum, Default, PartialEq)]
pub enum FrameArg {
    /// Local reference frame from the weighted covariance (rotation invariant).
    #[default]
    Lrf,
    /// World axes (thesis 4.4: translation-only matching).
    World,
}

#[derive(Debug, Args)]
#[command(group(clap::ArgGroup::new("which").required(true).args(["keypoints", "every"])))]
pub struct ShotArgs {
    /// Input: a PLY with x y z nx ny nz, or any mesh (area-weighted vertex normals are used).
    pub input: PathBuf,
    /// Support radius in model units.
    #[arg(long)]
    pub radius: f64,
    /// File of keypoint indices, one per line.
    #[arg(long)]
    pub keypoints: Option<PathBuf>,
    /// Use every K-th point as a keypoint.
    #[arg(long)]
    pub every: Option<usize>,
    /// Reference frame.
    #[arg(long, value_enum, default_value_t)]
    pub frame: FrameArg,
    /// Output: `.csv` (index, frame axes xx..zz, descriptor f0..f351) or anything else for the
    /// binary PEERSHOT layout.
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub json: JsonArg,
}

#[derive(Debug, Clone, Copy, ValueEnum, Default, PartialEq)]
pub enum IcpMetricArg {
    PointToPoint,
    #[default]
    PointToPlane,
}

#[derive(Debug, Clone, Copy, ValueEnum, Default, PartialEq)]
pub enum IcpMotionArg {
    #[default]
    Rigid,
    TranslationOnly,
}

#[derive(Debug, Args)]
pub struct AlignArgs {
    /// The shape to move.
    pub source: PathBuf,
    /// The shape to align to.
    pub target: PathBuf,
    /// Write the aligned source here (optional).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    #[arg(long, value_enum, default_value_t)]
    pub metric: IcpMetricArg,
    #[arg(long, value_enum, default_value_t)]
    pub motion: IcpMotionArg,
    /// Fraction of correspondences kept each iteration (trimmed ICP).
    #[arg(long, default_value_t = 0.9)]
    pub trim: f64,
    /// Maximum iterations.
    #[arg(long, default_value_t = 50)]
    pub iterations: usize,
    #[command(flatten)]
    pub encoding: EncodingArgs,
    #[command(flatten)]
    pub json: JsonArg,
}

#[derive(Debug, Args)]
pub struct ExampleArgs {
    /// Example name (see --list).
    #[arg(required_unless_present = "list")]
    pub name: Option<String>,
    /// Output mesh file. Also `-o OUTPUT`.
    #[arg(required_unless_present_any = ["list", "output_flag"])]
    pub output: Option<PathBuf>,
    /// The output, given as an option instead (as the pipeline commands take it).
    #[arg(short = 'o', long = "output", value_name = "OUTPUT", conflicts_with = "output")]
    pub output_flag: Option<PathBuf>,
    /// Also write the known structure (symmetries, cell pitch, instances) as JSON.
    #[arg(long, value_name = "FILE", value_parser = json_path)]
    pub structure: Option<PathBuf>,
    /// Also write the known symmetries as a motif_symmetry_v1 annotation (for `motif deform`).
    #[arg(long, value_name = "FILE", value_parser = json_path)]
    pub annotation: Option<PathBuf>,
    /// Also write a sample drag as motif_handles_v1: one end of the longest axis fixed, the other
    /// lifted over 30 frames.
    #[arg(long, value_name = "FILE", value_parser = json_path)]
    pub handles: Option<PathBuf>,
    /// List the available examples.
    #[arg(long)]
    pub list: bool,
    /// Benchmark scenes (scene-*): also write the building-block ground truth as JSON (the
    /// schema `motif eval` reads).
    #[arg(long, value_name = "FILE", value_parser = json_path)]
    pub gt: Option<PathBuf>,
    /// Benchmark scenes: noise, variation, occlusion, clutter and irregularity preset [default:
    /// medium].
    #[arg(long, value_enum)]
    pub difficulty: Option<DifficultyArg>,
    /// Benchmark scenes: number of points (default 300000).
    #[arg(long)]
    pub points: Option<usize>,
    /// Benchmark scenes: meshes used as extra building blocks, comma-separated (in
    /// `scene-parts` they replace the generated car, bin and lamp post).
    #[arg(long, value_delimiter = ',', value_name = "FILES", value_parser = listed_path)]
    pub parts: Vec<PathBuf>,
    #[command(flatten)]
    pub encoding: EncodingArgs,
}

#[derive(Debug, Clone, Copy, ValueEnum, Default, PartialEq)]
pub enum DifficultyArg {
    /// Regular placement, little noise, no variation, occlusion or clutter.
    Easy,
    /// Irregular placement, some noise and variation, three scanners, some clutter.
    #[default]
    Medium,
    /// Irregular placement, strong noise and variation, one scanner, clutter and outliers.
    Hard,
}

#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Folder for the demo's outputs (created; existing files in it are replaced).
    #[arg(long, short = 'o', visible_alias = "output", default_value = "motif-demo")]
    pub out: PathBuf,
    #[command(flatten)]
    pub json: JsonArg,
}

#[derive(Debug, Subcommand)]
pub enum MrfCommand {
    /// Solve an `mrf_grid_v1` problem (../shared/formats/mrf.md) by alpha-expansion.
    Solve(MrfSolveArgs),
    /// Write a random `mrf_grid_v1` problem of the shipped kind (for benchmarks against GCO).
    Generate(MrfGenerateArgs),
}

#[derive(Debug, Clone, Copy, ValueEnum, Default, PartialEq)]
pub enum LabelOrderArg {
    /// Labels 0, 1, ..., L-1 in every cycle.
    #[default]
    Sequential,
    /// A random permutation per cycle, drawn from --seed.
    Random,
}

#[derive(Debug, Clone, Copy, ValueEnum, Default, PartialEq)]
pub enum CyclesArg {
    /// Every label in every cycle until no move lowers the energy.
    Full,
    /// Labels whose last move succeeded first; stops earlier on easy problems.
    Adaptive,
    /// GCO's strategic queues: failed labels set aside, successful ones retried first.
    #[default]
    Queue,
}

#[derive(Debug, Clone, Copy, ValueEnum, Default, PartialEq)]
pub enum TiesArg {
    /// Among equally good cuts, switch the most sites to the move's label (GCO's choice).
    #[default]
    MostAlpha,
    /// Among equally good cuts, switch the fewest sites.
    FewestAlpha,
}

#[derive(Debug, Args)]
pub struct MrfSolveArgs {
    /// Problem file (JSON, format mrf_grid_v1).
    pub problem: PathBuf,
    /// Maximum expansion cycles.
    #[arg(long, default_value_t = 100)]
    pub max_cycles: usize,
    /// Label order within a cycle.
    #[arg(long, value_enum, default_value_t)]
    pub order: LabelOrderArg,
    /// Cycle strategy.
    #[arg(long, value_enum, default_value_t)]
    pub cycles: CyclesArg,
    /// Which cut a move applies when several are optimal.
    #[arg(long, value_enum, default_value_t)]
    pub ties: TiesArg,
    /// Build every move's graph anew instead of continuing from the same label's last move
    /// (flow recycling; same moves and result, only slower: for timing against GCO, which
    /// builds every move anew).
    #[arg(long)]
    pub no_recycle: bool,
    #[command(flatten)]
    pub json: JsonArg,
}

#[derive(Debug, Args)]
pub struct MrfGenerateArgs {
    /// Grid size as NX,NY,NZ.
    #[arg(long, value_delimiter = ',', default_value = "10,10,10")]
    pub dims: Vec<usize>,
    /// Number of labels.
    #[arg(long, default_value_t = 8)]
    pub labels: usize,
    /// Neighbourhood: 6 or 26.
    #[arg(long, default_value_t = 6)]
    pub connectivity: u32,
    /// Output JSON file (`-` prints it on stdout).
    #[arg(short, long, value_parser = json_path)]
    pub output: PathBuf,
}

#[derive(Debug, Subcommand)]
pub enum SymmetryCommand {
    /// Find global reflection planes and rotational symmetries and write a motif_symmetry_v1
    /// annotation (validated by closest-point residual).
    Detect(SymmetryDetectArgs),
    /// Validate an annotation against a mesh: group orders and, for every transform, the largest
    /// distance of a transformed region vertex to the surface (relative to the diagonal).
    Check(SymmetryCheckArgs),
}

#[derive(Debug, Args)]
pub struct SymmetryCheckArgs {
    /// The mesh.
    pub mesh: PathBuf,
    /// The annotation (motif_symmetry_v1).
    pub annotation: PathBuf,
    #[command(flatten)]
    pub json: JsonArg,
}

#[derive(Debug, Args)]
pub struct DeformArgs {
    /// Input mesh.
    pub mesh: PathBuf,
    /// Symmetry annotation (motif_symmetry_v1), e.g. from `motif symmetry detect`. Required
    /// unless --no-symmetry.
    #[arg(long, required_unless_present = "no_symmetry")]
    pub symmetry: Option<PathBuf>,
    /// Handles (motif_handles_v1); with `frames`, they are solved in sequence and the last is written.
    #[arg(long)]
    pub handles: PathBuf,
    /// Output mesh.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Sampling radius r (thesis 3.4) as a fraction of the bounding-box diagonal.
    #[arg(long, conflicts_with = "samples")]
    pub radius: Option<f64>,
    /// Target number of samples instead of a radius (default 400).
    #[arg(long)]
    pub samples: Option<usize>,
    /// Handle weight α of eq. 3.3.
    #[arg(long)]
    pub alpha: Option<f64>,
    /// Co-rotated Laplace iterations per frame (default 5).
    #[arg(long)]
    pub iterations: Option<usize>,
    /// Same pipeline with only the identity: shows what the symmetric basis buys.
    #[arg(long)]
    pub no_symmetry: bool,
    /// Also draw the rest shape and the deformed one side by side as a PNG, each handle marked
    /// (fixed ones in grey; dragged ones with an arrow from where they were to their target).
    #[arg(long, value_name = "PNG")]
    pub preview: Option<PathBuf>,
    #[command(flatten)]
    pub json: JsonArg,
}

#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Thesis Table 3.1: sizes, prefactor, solve (5 iterations), lift and frames per second.
    Deform(BenchDeformArgs),
    /// The studio's end-to-end frame time: drags a handle on a generated model in headless
    /// Chromium (needs scripts/studio-browser-setup.sh) and prints the median of every stage of a
    /// frame (request, server queue / solve / encode, reply, decode, GPU upload, render), the
    /// end-to-end time and the frame rate.
    Studio(BenchStudioArgs),
    /// Thesis 5.5: generated scenes at graded difficulty, scored for EM + SC, SC (no EM) and the
    /// supervised rigid-ICP baseline: mean precision, recall and F at τ = 0.125, time per stage.
    Detect(BenchDetectArgs),
    /// Thesis Fig. 4.8: retargeting with the detected offsets vs the dense MRF (nodes, labels,
    /// graph cut and step times, ratios), the interactive size (~1,000 nodes, 30 labels) and the
    /// alpha-expansion solver on mrf_grid_v1 problems next to GCO's times; medians.
    Retarget(BenchRetargetArgs),
}

#[derive(Debug, Args)]
pub struct BenchRetargetArgs {
    /// Runs per figure (medians are reported).
    #[arg(long, default_value_t = 5)]
    pub repeats: usize,
    /// Also the 30^3 grids with 64 labels (about a minute).
    #[arg(long)]
    pub large: bool,
    /// Skip the mrf_grid_v1 solver table.
    #[arg(long, conflicts_with = "large")]
    pub no_grids: bool,
    /// Folder of the shared meshes (default: $MOTIF_DATA, or shared/data above the current
    /// folder), for the rows of real grid-like models.
    #[arg(long, value_name = "DIR")]
    pub data: Option<std::path::PathBuf>,
    #[command(flatten)]
    pub json: JsonArg,
}

#[derive(Debug, Args)]
pub struct BenchDetectArgs {
    /// Scene kind (scene-facade, scene-street, scene-parts).
    #[arg(long, default_value = "scene-facade")]
    pub kind: String,
    /// Meshes used as extra building blocks of every scene, comma-separated (as `motif example
    /// --parts`); with `--kind scene-parts` the scenes hold these alone, e.g. the natural shapes of
    /// the shared data for the thesis's "non-man-made" figures.
    #[arg(long, value_delimiter = ',', value_name = "FILES", value_parser = listed_path)]
    pub parts: Vec<PathBuf>,
    /// Difficulty levels to run, comma-separated (all three by default); the table lists them from
    /// easy to hard.
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        value_name = "LEVELS",
        default_value = "easy,medium,hard"
    )]
    pub difficulty: Vec<DifficultyArg>,
    /// Scenes (seeds) per difficulty.
    #[arg(long, default_value_t = 2)]
    pub scenes: usize,
    /// Points per scene.
    #[arg(long, default_value_t = 300_000)]
    pub points: usize,
    /// ε relative to the principal-axes diagonal, fixed for the whole benchmark as the thesis fixes
    /// one per dataset (0.0012 ≈ 4 cm on the ~33 m generated facades: 64ε spans a window).
    #[arg(long, default_value_t = 0.0012)]
    pub epsilon: f64,
    /// Minimum |Ψ(i, j)| of a co-occurring word pair (thesis 5.4: 5 for single shapes, 10 for
    /// city scans; the detector's default is 5). The generated scenes' smaller blocks repeat 2–6
    /// times, so their word pairs rarely reach 5 matches. Measured before the peak test
    /// (`--peak-share 0`): with 4, over seeds 1–6, medium F rose (facade 0.822 → 0.854, street
    /// 0.658 → 0.703) but hard facades lost (F 0.451 → 0.439; SC gained more than EM + SC). With
    /// the peak test, 3 lowered street F on seeds 1–3 at every level. The benchmark keeps the
    /// thesis's 5.
    #[arg(long, default_value_t = 5)]
    pub min_support: usize,
    /// Minimum share of a word pair's hypotheses its best local transform must gather (see
    /// `motif detect --peak-share`; 0 is the thesis's Match).
    #[arg(long, default_value_t = 0.125)]
    pub peak_share: f64,
    /// Skip the rigid-ICP baseline (the slowest column).
    #[arg(long)]
    pub no_icp: bool,
    /// Instance extents and regrouping by size (see `motif detect --regroup`); `none` for the
    /// thesis's output.
    #[arg(long, value_enum, default_value_t = RegroupArg::Extent, value_name = "MODE")]
    pub regroup: RegroupArg,
    /// Classes of unexplained segments repeated by size, and long ones by shape (see `motif detect
    /// --repeated-segments`).
    #[arg(long, value_enum, default_value_t = RepeatedSegmentsArg::Classes, value_name = "MODE")]
    pub repeated_segments: RepeatedSegmentsArg,
    /// Keep the classes of the size split and merge instead of moving each instance to the class
    /// whose depth images of the surroundings its own resembles and then dropping classes and
    /// instances whose images disagree (a step of the extent stage, motif_detect::content; not
    /// in the thesis, on by default: under strong variation window styles share their sizes but
    /// not their transoms and shutters, and clutter boxes of unlike sizes form classes whose
    /// images share nothing). No effect with `--regroup none`.
    #[arg(long)]
    pub no_content: bool,
    /// Keep the classes of the content step instead of grouping the instances again by their
    /// depth images, drawn at one common scale and compared at the best of a few shifts (the
    /// extent stage's last step, motif_detect::aligned; not in the thesis, on by default: a box
    /// fitted to half a window, or without its shutters, still finds the window under it). No
    /// effect with `--regroup none`.
    #[arg(long)]
    pub no_aligned: bool,
    /// How that last step groups the instances it pictures (those of each thin axis whose box
    /// is flat): `communities` forms the classes again as the communities of the graph of those
    /// instances weighted by image distance (joins one style found as several classes, splits a
    /// class of two); `reassign` keeps the classes and moves each instance to the one whose
    /// members it resembles most. No effect with `--no-aligned` or `--regroup none`.
    #[arg(long, value_enum, default_value_t = AlignedGroupingArg::Communities)]
    pub aligned_grouping: AlignedGroupingArg,
    /// Compare the aligned step's depth images also where the box of a block that stands in
    /// front (a balcony, a car: a box the step does not picture) covers them, instead of
    /// leaving those cells out (motif_detect::aligned, "What stands in front"). No effect with
    /// `--no-aligned` or `--regroup none`.
    #[arg(long)]
    pub no_aligned_mask: bool,
    /// Measure every unexplained segment along its principal axes when grouping segments by
    /// size, also one that stands on a support plane (the ground, the wall), instead of by its
    /// height above the plane and its footprint on it (motif_detect::segment_classes, "On a
    /// support plane"). No effect with `--regroup none` or `--repeated-segments none`.
    #[arg(long)]
    pub no_segment_support: bool,
    /// Do not search each class's plane for copies that no instance covers, by its members'
    /// depth images (the extent stage's last step, motif_detect::copies; not in the thesis, on
    /// by default: a style whose other copies a class absorbed keeps too few copies for the
    /// co-occurrence analysis). No effect with `--no-aligned` or `--regroup none`.
    #[arg(long)]
    pub no_copies: bool,
    /// Do not group free-standing blocks by their shapes (the extent stage's step after the
    /// copies, motif_detect::shape_split; not in the thesis, on by default: smooth blocks of
    /// different shapes can share one class of co-occurring features, and one shape can be
    /// found as two classes). No effect with `--regroup none`.
    #[arg(long)]
    pub no_shape_split: bool,
    /// Group the free-standing blocks by shape within each class only (the step's first
    /// version: it splits classes but never joins or corrects them), instead of across classes.
    #[arg(long, conflicts_with = "no_shape_split")]
    pub shape_split_per_class: bool,
    /// Also print, per level and annotated class, how many instances EM + SC located (some
    /// detected box matches) and how many the recall credited, summed over the scenes, and the
    /// R and F that no grouping or pruning of its boxes can exceed (the JSON report always has
    /// them, for every method).
    #[arg(long)]
    pub per_class: bool,
    /// The table as a picture (PNG): mean F per difficulty and method with its standard error,
    /// beside the thesis's figure and the target, and the stress curves of every row.
    #[arg(long, value_name = "PNG")]
    pub plot: Option<PathBuf>,
    /// EM + SC on the medium scenes (or the first level run): mean PR curve, stress curve and
    /// per-class shares of located and credited instances (PNG, as `motif eval --plot`).
    #[arg(long, value_name = "PNG")]
    pub plot_detail: Option<PathBuf>,
    #[command(flatten)]
    pub json: JsonArg,
}

#[derive(Debug, Args)]
pub struct BenchStudioArgs {
    /// Mouse-move steps of the drag (frames are fewer when solves are slower than the mouse).
    #[arg(long, default_value_t = 200)]
    pub steps: usize,
    /// Generated example to drag (see `motif example --list`).
    #[arg(long, default_value = "windmill_100k")]
    pub example: String,
    /// Browser window width, pixels (the 3D view is the window less the 330-pixel side panel).
    #[arg(long, default_value_t = 1280)]
    pub width: u32,
    /// Browser window height, pixels.
    #[arg(long, default_value_t = 720)]
    pub height: u32,
}

#[derive(Debug, Args)]
pub struct BenchDeformArgs {
    /// Frames timed per model (medians are reported).
    #[arg(long, default_value_t = 60)]
    pub frames: usize,
    /// Folder of real meshes (default: ../shared/data or $MOTIF_DATA when present).
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Only the generated examples.
    #[arg(long)]
    pub generated_only: bool,
    #[command(flatten)]
    pub json: JsonArg,
}

#[derive(Debug, Args)]
pub struct SymmetryDetectArgs {
    /// Input mesh.
    pub mesh: PathBuf,
    /// Output annotation (JSON, motif_symmetry_v1).
    #[arg(short, long, value_parser = json_path)]
    pub output: PathBuf,
    /// Accept a symmetry when the largest distance of transformed surface samples to the surface
    /// is below this fraction of the bounding-box diagonal.
    #[arg(long, default_value_t = 1e-3)]
    pub tolerance: f64,
    /// Highest rotation order tested.
    #[arg(long, default_value_t = 24)]
    pub max_order: u32,
    /// Also annotate approximate symmetries (residual below 1e-2 of the diagonal).
    #[arg(long)]
    pub approximate: bool,
    /// Also draw the model and its symmetry elements as a PNG: the global group's mirror planes
    /// (orange outlines) and rotation axes (green), and the partial groups' elements (pink),
    /// each labelled.
    #[arg(long, value_name = "PNG")]
    pub plot: Option<PathBuf>,
    #[command(flatten)]
    pub json: JsonArg,
}

#[derive(Debug, Args)]
pub struct OffsetsArgs {
    /// Input mesh.
    pub mesh: PathBuf,
    /// Picture of the offset histogram (three projections; offsets in one plane get that plane
    /// alone, along one line a profile) with the chosen offsets (PNG).
    #[arg(long, value_name = "PNG")]
    pub plot: Option<PathBuf>,
    /// τ of eq. 4.1: minimum offset length, in units of the normalised model ([-1, 1]).
    #[arg(long, default_value_t = 0.15)]
    pub tau: f64,
    #[command(flatten)]
    pub json: JsonArg,
}

#[derive(Debug, Args)]
pub struct SparsityArgs {
    /// A MANIFEST.json (categories from it), or mesh files and folders (category from a parent
    /// folder named man-made or natural).
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// Cumulative distributions per category and τ (PNG).
    #[arg(long, value_name = "PNG")]
    pub plot: Option<PathBuf>,
    #[command(flatten)]
    pub json: JsonArg,
}

#[derive(Debug, Clone, Copy, ValueEnum, Default, PartialEq)]
pub enum RetargetMethodArg {
    /// Voxels and labels from the detected principal offsets (thesis 4.2.2).
    #[default]
    Offsets,
    /// The dense-MRF baseline: regular offsets of 0.1 (thesis 4.5).
    Dense,
}

#[derive(Debug, Args)]
#[command(group(clap::ArgGroup::new("size").required(true).args(["steps", "target_size"])))]
pub struct RetargetArgs {
    /// Input mesh.
    pub mesh: PathBuf,
    /// Output mesh.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Principal offsets to add per direction, as U,V,W (negative shrinks), e.g. 2,1,0.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, value_parser = step_count)]
    pub steps: Option<Vec<i32>>,
    /// Desired bounding-box size X,Y,Z in model units; rounded to whole offsets. `-` keeps an
    /// axis's size (e.g. 3,-,-).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub target_size: Option<Vec<SizeArg>>,
    /// Offsets (detected) or the dense baseline.
    #[arg(long, value_enum, default_value_t)]
    pub method: RetargetMethodArg,
    /// Principal offsets to use instead of the detected ones, in model units: one to three
    /// independent vectors X,Y,Z separated by ';' (e.g. '0.16,0,0;0,0,0.16'), for a pitch the user
    /// knows and the detection misses or refuses (a brick of two studs per side). The detection
    /// still runs for its features and report, but its repetition verdict is not applied.
    #[arg(long, value_name = "X,Y,Z[;X,Y,Z...]", allow_hyphen_values = true)]
    pub offsets: Option<String>,
    /// Leave the openings of cuts that no copy continues open instead of capping them (openings
    /// along the input's own open boundary are never capped). The fill that follows closes what
    /// it can of them as holes: with --no-fill too, they stay open.
    #[arg(long)]
    pub no_caps: bool,
    /// Leave the holes still open after capping as they are instead of filling them (slits along
    /// seams where neighbouring copies differ; holes along the input's own open boundary are
    /// never filled)
    #[arg(long)]
    pub no_fill: bool,
    /// When the model has no repetition, scale it to --target-size instead of failing.
    #[arg(long)]
    pub plain_resize: bool,
    /// How triangles travel with the voxels: `cut` (cut at voxel faces first, so that long
    /// triangles spanning several cells stretch with the model) or `centroid` (whole, by the voxel
    /// of their centroid; keeps the tessellation exactly, but leaves gaps along the seams that
    /// capping and filling do not always close, also on closed models).
    #[arg(long, value_enum, default_value_t = AssignmentArg::Cut)]
    pub assignment: AssignmentArg,
    /// Also write a picture of the input and the result side by side (PNG), seen along the normal
    /// of the plane of the first two principal offsets.
    #[arg(long, value_name = "PNG")]
    pub preview: Option<PathBuf>,
    #[command(flatten)]
    pub json: JsonArg,
}

/// One size of `--target-size`: a length in model units, or `-` (also `keep`) for the size the
/// model has along that axis.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SizeArg(pub Option<f64>);

impl std::str::FromStr for SizeArg {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "-" | "keep" => Ok(SizeArg(None)),
            t => t.parse::<f64>().map(|v| SizeArg(Some(v))).map_err(|_| {
                format!("{s:?} is not a size: give a length in model units, or - to keep the model's size")
            }),
        }
    }
}

/// `--assignment` of `motif retarget`.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum AssignmentArg {
    /// Whole triangles, by the voxel containing their centroid.
    Centroid,
    /// Triangles cut at the voxel faces first.
    Cut,
}

#[derive(Debug, Args)]
pub struct DetectArgs {
    /// A point cloud (PLY with normals preferred; normals are estimated when absent) or a mesh
    /// (sampled first).
    pub input: PathBuf,
    /// The detection (../shared/formats/detection.md): classes, instance boxes, transforms, points.
    #[arg(short, long, value_name = "RESULT.json", value_parser = json_path)]
    pub output: PathBuf,
    /// A PLY of the input points with `class` and `instance` labels (-1 for background) and colours.
    #[arg(long, value_name = "PLY")]
    pub labels: Option<PathBuf>,
    /// The classes as a motif_symmetry_v1 annotation of instance sets (for `motif deform`).
    #[arg(long, value_name = "ANNOT.json", value_parser = json_path)]
    pub as_symmetry: Option<PathBuf>,
    /// A picture of the detection (PNG): the points seen along two axes, coloured by class, with
    /// every instance's box.
    #[arg(long, value_name = "PNG")]
    pub plot: Option<PathBuf>,
    /// Skip the EM refinement: spectral clustering on the initial dictionary (the thesis's "SC").
    #[arg(long)]
    pub no_em: bool,
    /// ε relative to the principal-axes diagonal (thesis 5.4: 0.0005 for shapes, 0.00005 for city
    /// scans). Default: the thesis's 0.0005 or 1.02 × the input's median point spacing, whichever
    /// is larger.
    #[arg(long, conflicts_with = "epsilon_abs")]
    pub epsilon: Option<f64>,
    /// ε in the input's units instead.
    #[arg(long, value_name = "LENGTH")]
    pub epsilon_abs: Option<f64>,
    /// Threshold on the dimensionless curvature |κ₁|·4ε of features (thesis 5.4: 0.15).
    #[arg(long, default_value_t = 0.15)]
    pub kappa: f64,
    /// At most this many features, strongest curvature first (not in the thesis; bounds the cost
    /// on noisy scans).
    #[arg(long, default_value_t = 4_000)]
    pub max_features: usize,
    /// K, dictionary size (thesis 5.4: 100).
    #[arg(long, default_value_t = 100)]
    pub words: usize,
    /// σ of the matching score m(x, y) (thesis 5.4: 0.1).
    #[arg(long, default_value_t = 0.1)]
    pub sigma: f64,
    /// Descriptor distance, in units of the median within-cluster distance d̂, at which the matching
    /// score is 0.5 for σ = 0.1 (Motif's unit for the thesis's m(x, y); see motif_detect::dictionary).
    #[arg(long, default_value_t = 1.0)]
    pub tolerance: f64,
    /// Minimum matching score of the sliding window (thesis 5.4: 0.5).
    #[arg(long, default_value_t = 0.5)]
    pub min_score: f64,
    /// Maximum EM iterations (thesis 5.4: 5).
    #[arg(long, default_value_t = 5)]
    pub em_iterations: usize,
    /// Minimum |Ψ(i, j)| of a co-occurring pair (thesis 5.4: 5 for shapes, 10 for city scans).
    #[arg(long, default_value_t = 5)]
    pub min_support: usize,
    /// A pair co-occurs only when its best local transform gathers at least this share of the
    /// pair's hypotheses (member pairs within 64ε); 1/8 is what chance gives along a crease
    /// (see motif_detect::EmOptions::peak_share). 0 is the thesis's Match.
    #[arg(long, default_value_t = 0.125)]
    pub peak_share: f64,
    /// σ_s of eq. 5.1, in ε (thesis 5.4: 16).
    #[arg(long, default_value_t = 16.0)]
    pub sigma_s: f64,
    /// Mean-shift bandwidth in the MDS embedding (thesis 5.4: 0.5).
    #[arg(long, default_value_t = 0.5)]
    pub bandwidth: f64,
    /// Rounds of MDL incremental detection (thesis 5.4); each keeps the classes of one cluster.
    #[arg(long, default_value_t = 7)]
    pub classes: usize,
    /// MDL stopping rule: a round's classes are kept only when they save at least this fraction
    /// of all features (see motif_detect::DetectOptions::mdl_min_saving).
    #[arg(long, default_value_t = 0.005)]
    pub mdl_min_saving: f64,
    /// Points sampled on a mesh input.
    #[arg(long, default_value_t = 300_000)]
    pub mesh_samples: usize,
    /// After the co-occurrence stages, grow instance boxes to their segment (off the wall and
    /// ground planes), drop instances that then repeat one of their class, and split and merge
    /// classes by size (motif_detect::extent; not in the thesis, on by default: it raised F at
    /// every level of the benchmark scenes). `none` gives the thesis's boxes and classes.
    #[arg(long, value_enum, default_value_t = RegroupArg::Extent, value_name = "MODE")]
    pub regroup: RegroupArg,
    /// A step of the extent stage (motif_detect::segment_classes; not in the thesis, on by
    /// default): segments of the scan that no class explains (off the wall and ground planes, at
    /// least one HOC cell wide in two directions, with enough features) are grouped by their
    /// sizes along their own axes, and groups of three or more that stand out of the size
    /// distribution become classes; then those longer than 64ε that no group took are grouped
    /// by shape (how much of each lies on the other once aligned), so lamp posts partly hidden
    /// behind cars still form a class. These are blocks the co-occurrence analysis cannot link,
    /// such as lamp posts taller than 64ε and bins with few features. `sizes` leaves out the
    /// groups by shape. No effect with `--regroup none`.
    #[arg(long, value_enum, default_value_t = RepeatedSegmentsArg::Classes, value_name = "MODE")]
    pub repeated_segments: RepeatedSegmentsArg,
    /// Keep the classes of the size split and merge instead of moving each instance to the class
    /// whose depth images of the surroundings its own resembles and then dropping classes and
    /// instances whose images disagree (a step of the extent stage, motif_detect::content; not
    /// in the thesis, on by default: under strong variation window styles share their sizes but
    /// not their transoms and shutters, and clutter boxes of unlike sizes form classes whose
    /// images share nothing). No effect with `--regroup none`.
    #[arg(long)]
    pub no_content: bool,
    /// Keep the classes of the content step instead of grouping the instances again by their
    /// depth images, drawn at one common scale and compared at the best of a few shifts (the
    /// extent stage's last step, motif_detect::aligned; not in the thesis, on by default: a box
    /// fitted to half a window, or without its shutters, still finds the window under it). No
    /// effect with `--regroup none`.
    #[arg(long)]
    pub no_aligned: bool,
    /// How that last step groups the instances it pictures (those of each thin axis whose box
    /// is flat): `communities` forms the classes again as the communities of the graph of those
    /// instances weighted by image distance (joins one style found as several classes, splits a
    /// class of two); `reassign` keeps the classes and moves each instance to the one whose
    /// members it resembles most. No effect with `--no-aligned` or `--regroup none`.
    #[arg(long, value_enum, default_value_t = AlignedGroupingArg::Communities)]
    pub aligned_grouping: AlignedGroupingArg,
    /// Compare the aligned step's depth images also where the box of a block that stands in
    /// front (a balcony, a car: a box the step does not picture) covers them, instead of
    /// leaving those cells out (motif_detect::aligned, "What stands in front"). No effect with
    /// `--no-aligned` or `--regroup none`.
    #[arg(long)]
    pub no_aligned_mask: bool,
    /// Measure every unexplained segment along its principal axes when grouping segments by
    /// size, also one that stands on a support plane (the ground, the wall), instead of by its
    /// height above the plane and its footprint on it (motif_detect::segment_classes, "On a
    /// support plane"). No effect with `--regroup none` or `--repeated-segments none`.
    #[arg(long)]
    pub no_segment_support: bool,
    /// Do not search each class's plane for copies that no instance covers, by its members'
    /// depth images (the extent stage's last step, motif_detect::copies; not in the thesis, on
    /// by default: a style whose other copies a class absorbed keeps too few copies for the
    /// co-occurrence analysis). No effect with `--no-aligned` or `--regroup none`.
    #[arg(long)]
    pub no_copies: bool,
    /// Do not group free-standing blocks by their shapes (the extent stage's step after the
    /// copies, motif_detect::shape_split; not in the thesis, on by default: smooth blocks of
    /// different shapes can share one class of co-occurring features, and one shape can be
    /// found as two classes). No effect with `--regroup none`.
    #[arg(long)]
    pub no_shape_split: bool,
    /// Group the free-standing blocks by shape within each class only (the step's first
    /// version: it splits classes but never joins or corrects them), instead of across classes.
    #[arg(long, conflicts_with = "no_shape_split")]
    pub shape_split_per_class: bool,
    /// Keep the extent stage's boxes as grown instead of fitting each to the points it holds
    /// (a step of the stage, on by default: boxes padded around creases and grown to segments
    /// reach past the block; fitted, they overlap the true blocks more, F at τ = 0.5 rose from
    /// 0.29 to 0.65 on medium street scenes). No effect with `--regroup none`.
    #[arg(long)]
    pub no_box_fit: bool,
    /// Share of a box's points ignored at each end of each axis when it is fitted (stray
    /// outliers).
    #[arg(long, default_value_t = 0.002, value_name = "SHARE")]
    pub fit_trim: f64,
    #[command(flatten)]
    pub json: JsonArg,
}

#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Pairs of files: RESULT.json GT.json [RESULT2.json GT2.json ...] (../shared/formats/detection.md).
    #[arg(required = true, num_args = 2..)]
    pub files: Vec<PathBuf>,
    /// Minimum overlap ratio vol(A∩B)/max(vol(A), vol(B)) for two boxes to match.
    #[arg(long, default_value_t = 0.125)]
    pub tau: f64,
    /// PR curve, stress curve and per-class shares of located and credited instances (PNG).
    #[arg(long, value_name = "PNG")]
    pub plot: Option<PathBuf>,
    /// Also print, per annotated class (summed by name over the scenes), how many instances some
    /// detected box locates and how many the recall credits, and the R and F that no grouping or
    /// pruning of these boxes can exceed; for one scene, also per detected class how many
    /// instances the precision credits. The JSON report always has them.
    #[arg(long)]
    pub per_class: bool,
    #[command(flatten)]
    pub json: JsonArg,
}

#[derive(Debug, Subcommand)]
pub enum BaselineCommand {
    /// Supervised rigid-ICP sliding window (thesis 5.5.3 "RigidICP"): each ground-truth class's
    /// first instance is the template, slid over the scene and refined by ICP.
    RigidIcp(RigidIcpArgs),
}

#[derive(Debug, Args)]
pub struct RigidIcpArgs {
    /// Scene point cloud (PLY with normals: point-to-plane ICP; without: point-to-point).
    pub scene: PathBuf,
    /// Ground truth (../shared/formats/detection.md): its classes and first-instance templates.
    #[arg(long)]
    pub gt: PathBuf,
    /// Detection result (JSON, the schema motif eval reads).
    #[arg(short, long, value_parser = json_path)]
    pub output: PathBuf,
    /// Window grid step, in template diagonals.
    #[arg(long, default_value_t = 0.2)]
    pub step: f64,
    /// Minimum score: the smaller of the fractions of template points near the scene and of scene
    /// points in the box near the template.
    #[arg(long, default_value_t = 0.5)]
    pub min_score: f64,
    /// Inlier distance, in template diagonals.
    #[arg(long, default_value_t = 0.01)]
    pub inlier_distance: f64,
    /// Yaw angles tried for classes that are rotated about the up axis.
    #[arg(long, default_value_t = 12)]
    pub rotation_steps: usize,
    /// Which classes are searched over rotations about the up axis.
    #[arg(long, value_enum, default_value_t)]
    pub rotations: RotationsArg,
    #[command(flatten)]
    pub json: JsonArg,
}

#[derive(Debug, Clone, Copy, ValueEnum, Default, PartialEq)]
pub enum RotationsArg {
    /// Classes whose annotated instances are rotated about the up axis.
    #[default]
    Auto,
    /// None.
    Never,
    /// All.
    Always,
}

/// The output file of a command that takes it as its last argument or as `-o` (clap requires
/// exactly one of the two).
fn output_of<'a>(positional: &'a Option<PathBuf>, flag: &'a Option<PathBuf>) -> &'a std::path::Path {
    positional.as_deref().or(flag.as_deref()).expect("clap requires the output as an argument or -o")
}

/// `output()`: the output file of a command that takes it as an argument or as `-o`.
macro_rules! output_argument_or_flag {
    ($($args:ty),*) => {$(
        impl $args {
            /// The output file (argument or `-o`).
            pub fn output(&self) -> &std::path::Path {
                output_of(&self.output, &self.output_flag)
            }
        }
    )*};
}

output_argument_or_flag!(ConvertArgs, SampleArgs, NormalsArgs, CurvatureArgs);

impl ExampleArgs {
    /// The output file (argument or `-o`), if any (`--list` needs none).
    pub fn output(&self) -> Option<&std::path::Path> {
        self.output.as_deref().or(self.output_flag.as_deref())
    }
}
